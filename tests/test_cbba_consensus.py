"""CBBA's decision logic (mrta_agent.cbba) against the paper's guarantees (Choi, Brunet & How,
IEEE T-RO 25(4), 2009): in synchronous rounds (mrta_agent.cbba.synchronous, the model of the
paper's theorem) a team converges to the sequential greedy algorithm's assignment and paths —
on a full graph and on connected ones, within N_min · D rounds — and scores at least half the
exact optimum. The greedy algorithm, the score and the optimum are restated from their
definitions in tests/harness/cbba_reference.py; nothing of mrta_zenoh.planning.insertion computes what
is checked."""

from __future__ import annotations

import collections
import itertools
import math
import random

import pytest

from mrta_agent.cbba.bundle import Cbba
from mrta_agent.cbba.messages import Bids
from mrta_agent.cbba.synchronous import run_rounds
from mrta_agent.cbba.table import NONE
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.cbba_reference import LAMBDA, greedy, marginal, optimum, random_instance, score


# ------------------------------------------------------------------ teams
def team_of(p: Problem, **kw) -> dict[str, Cbba]:
    kw.setdefault("lookahead", math.inf)
    return {r.id: Cbba(p, r.id, resend_period=0.0, **kw) for r in p.robots}


def paths(team, p: Problem) -> dict[int, list[int]]:
    return {p.robot_index(r): logic.path for r, logic in team.items()}


def assert_conflict_free(team) -> None:
    """Every robot believes the same winners, and each task is in its winner's bundle only."""
    views = {tuple(logic.z) for logic in team.values()}
    assert len(views) == 1
    (z,) = views
    held = collections.Counter(j for logic in team.values() for j in logic.bundle)
    assert all(count == 1 for count in held.values())
    for logic in team.values():
        assert {j for j, w in enumerate(z) if w == logic.i} == set(logic.bundle)


def diameter(ids, edge) -> int:
    longest = 0
    for source in ids:
        dist, queue = {source: 0}, collections.deque([source])
        while queue:
            u = queue.popleft()
            for v in ids:
                if v not in dist and edge(u, v):
                    dist[v] = dist[u] + 1
                    queue.append(v)
        assert len(dist) == len(ids), "the graph must be connected"
        longest = max(longest, max(dist.values()))
    return longest


# ------------------------------------------------------------------ the guarantees
@pytest.mark.slow
def test_converged_cbba_is_the_sequential_greedy_assignment_and_paths():
    rng = random.Random(400)
    for _ in range(120):
        p = random_instance(rng, rng.randint(2, 5), rng.randint(3, 9))
        team = team_of(p)
        rounds = run_rounds(team)
        routes, picks = greedy(p)
        assert paths(team, p) == routes
        assert_conflict_free(team)
        bids = {j: value for _, j, value in picks}
        assert {j: team["r0"].y[j] for j in bids} == pytest.approx(bids)
        assert rounds <= 1 + len(p.tasks)  # round 1 builds bundles; then N_t · D, D = 1


@pytest.mark.parametrize("shape", ["line", "ring", "random"])
def test_on_a_connected_graph_cbba_converges_conflict_free_within_nt_times_d_rounds(shape):
    rng = random.Random(401 + len(shape))
    for _ in range(35):
        p = random_instance(rng, rng.randint(3, 6), rng.randint(3, 8))
        ids = [r.id for r in p.robots]
        order = ids[:]
        rng.shuffle(order)
        place = {r: k for k, r in enumerate(order)}
        if shape == "line":
            edges = {frozenset((a, b)) for a, b in zip(order, order[1:])}
        elif shape == "ring":
            edges = {frozenset((a, b)) for a, b in zip(order, order[1:] + order[:1])}
        else:  # a random tree plus random chords
            edges = {frozenset((r, order[rng.randrange(place[r])])) for r in order[1:]}
            edges |= {frozenset(pair) for pair in itertools.combinations(ids, 2)
                      if rng.random() < 0.2}

        def edge(a, b):
            return frozenset((a, b)) in edges

        d = diameter(ids, edge)
        team = team_of(p)
        rounds = run_rounds(team, neighbours=edge)
        assert_conflict_free(team)
        assert rounds <= 1 + len(p.tasks) * d
        assert paths(team, p) == greedy(p)[0]  # the paper proves it for any connected graph


def test_the_bundle_limit_caps_bundles_and_the_bound_becomes_lt_times_robots():
    rng = random.Random(402)
    for _ in range(30):
        p = random_instance(rng, rng.randint(2, 4), rng.randint(4, 9))
        team = team_of(p, bundle_limit=2)
        rounds = run_rounds(team)
        assert all(len(logic.bundle) <= 2 for logic in team.values())
        assert paths(team, p) == greedy(p, limit=2)[0]
        assert rounds <= 1 + min(len(p.tasks), 2 * len(p.robots))


def test_cbba_scores_at_least_half_the_exact_optimum_on_small_instances():
    rng = random.Random(403)
    worst = math.inf
    for _ in range(40):
        p = random_instance(rng, rng.randint(2, 3), rng.randint(2, 6))
        team = team_of(p)
        run_rounds(team)
        got = sum(score(p, p.robot_index(r), logic.path) for r, logic in team.items())
        best = optimum(p)
        assert got <= best + 1e-9
        worst = min(worst, got / best)
    assert worst >= 0.5


# ------------------------------------------------------------------ where we depart from the paper
STALE = Problem((Robot("r0", (4, 9), 1.0), Robot("r1", (5, 4), 1.0), Robot("r2", (0, 6), 1.0)),
                (Task("t0", (9, 8)), Task("t1", (2, 1)), Task("t2", (9, 2)), Task("t3", (5, 7)),
                 Task("t4", (6, 8))))
CYCLE = Problem((Robot("r0", (4, 8), 1.0), Robot("r1", (1, 4), 1.0)),
                (Task("t0", (8, 10)), Task("t1", (0, 10)), Task("t2", (0, 10))))


def test_the_discounted_score_does_not_always_diminish():
    # one robot at (0, 0), speed 1; A at (10, 0), B at (0, 4), j at (0, 5). On route [A], j
    # first delays A from 10 to 5 + √125. Once B is on the route (first: it is on the way to
    # j), A is reached at 4 + √116 already, so j's delay to it costs less: j is worth more
    # after B was added — the paper's diminishing marginal gain does not hold
    p = Problem((Robot("r", (0.0, 0.0), 1.0),),
                (Task("A", (10.0, 0.0)), Task("B", (0.0, 4.0)), Task("j", (0.0, 5.0))))
    assert marginal(p, 0, [0], 1)[1] == 0  # B goes before A
    without_b = marginal(p, 0, [0], 2)
    with_b = marginal(p, 0, [1, 0], 2)
    assert without_b == (pytest.approx(LAMBDA ** 5 - LAMBDA ** 10 + LAMBDA ** (5 + 125 ** 0.5)), 0)
    assert with_b[0] > without_b[0]
    # CBBA bids the least over the bundle's stages, which does diminish
    logic = Cbba(p, "r", lookahead=math.inf)
    logic.tick(0.0)
    assert logic.bundle[:2] == [1, 0] or logic.y[2] <= logic.y[logic.bundle[0]]


def test_the_published_rules_can_cycle_for_ever_where_the_score_does_not_diminish():
    with pytest.raises(RuntimeError, match="did not settle"):
        run_rounds(team_of(CYCLE, diminishing=False, recheck=False), max_rounds=300)
    team = team_of(CYCLE)
    run_rounds(team)
    assert paths(team, CYCLE) == greedy(CYCLE)[0]


def test_without_the_recheck_a_stale_bundle_settles_away_from_the_greedy_assignment():
    # with the diminishing score (which has DMG by construction) the published bundle
    # construction keeps a task added while a better one looked taken
    team = team_of(STALE, recheck=False)
    run_rounds(team)
    assert paths(team, STALE) != greedy(STALE)[0]
    assert_conflict_free(team)
    team = team_of(STALE)
    run_rounds(team)
    assert paths(team, STALE) == greedy(STALE)[0]


# ------------------------------------------------------------------ a changing team and tasks
def test_after_a_robot_leaves_the_team_converges_to_the_greedy_assignment_without_it():
    rng = random.Random(404)
    for _ in range(25):
        p = random_instance(rng, rng.randint(3, 5), rng.randint(3, 9))
        team = team_of(p)
        last = run_rounds(team)
        gone = rng.choice([r.id for r in p.robots])
        k = p.robot_index(gone)
        del team[gone]
        for logic in team.values():
            logic.teammate(gone, False)
        run_rounds(team, start=last + 1)
        assert all(k not in logic.z for logic in team.values())
        assert_conflict_free(team)
        rest = [i for i in range(len(p.robots)) if i != k]
        assert paths(team, p) == greedy(p, robots=rest)[0]


def test_a_departed_robot_named_in_relayed_news_reads_as_no_winner():
    p = Problem((Robot("r0", (0, 0), 1.0), Robot("r1", (1, 0), 1.0), Robot("r2", (9, 0), 1.0)),
                (Task("a", (1, 1)),))
    team = team_of(p)
    run_rounds(team)
    logic = team["r0"]
    assert logic.winners() == {"a": "r1"}
    logic.teammate("r1", False)
    assert logic.winners() == {}
    # r2 has not seen r1 go, and has later news of it than r0: Table 1 (row 13) would take
    # r1 back as the winner
    news = Bids(Header("r2", 99.0, 1), ((0, 1, 0.9),), ((1, 99.0), (2, 99.0)), (), 9.0, 0.0)
    assert logic.hear("bids", "r2", news, 99.0)
    assert logic.z[0] == NONE


def test_tasks_that_arrive_later_are_bid_on_from_their_arrival():
    rng = random.Random(405)
    for _ in range(15):
        p = random_instance(rng, 3, 7)
        late = Problem(p.robots, tuple(Task(t.id, t.position, arrival=60.0 if j >= 4 else 0.0,
                                            capability=t.capability)
                                       for j, t in enumerate(p.tasks)))
        team = team_of(late, lookahead=0.0)  # a round's time is its number
        last = run_rounds(team)
        assert last < 60
        assert paths(team, late) == greedy(late, tasks=range(4))[0]
        run_rounds(team, start=60)
        assert paths(team, late) == greedy(late)[0]
        assert_conflict_free(team)


def test_one_message_heard_by_many_robots_is_read_once_and_acts_as_a_copy_each():
    """In an agent host (and in the synchronous rounds) one message object reaches every
    robot: what it says is read once (cbba/reading.py), and each robot ends as it would
    hearing a copy of its own — among them one whose out-of-range bid is refused whole."""
    from mrta_agent.cbba import reading
    from mrta_zenoh import codec

    p = random_instance(random.Random(5), 4, 6)
    ids = [r.id for r in p.robots]
    sender = Cbba(p, ids[0], resend_period=0.0, lookahead=math.inf)
    fields = sender.tick(0.0)[0].fields
    good = Bids(header=Header(ids[0], 0.0, 1), **fields)
    bad = Bids(header=Header(ids[0], 0.5, 2), **{**fields, "winners": fields["winners"] + (
        (len(p.tasks) - 1, 0, 1e9),)})
    shared = {r: Cbba(p, r, resend_period=0.0, lookahead=math.inf) for r in ids[1:]}
    copied = {r: Cbba(p, r, resend_period=0.0, lookahead=math.inf) for r in ids[1:]}
    for msg in (good, bad):
        for r in ids[1:]:
            shared[r].hear("bids", ids[0], msg, msg.header.stamp)
            copied[r].hear("bids", ids[0], codec.decode(Bids.TYPE_NAME, codec.encode(msg)),
                           msg.header.stamp)
    assert reading.read(good) is reading.read(good)  # read once
    for r in ids[1:]:
        a, b = shared[r], copied[r]
        assert (a.z, a.y, a.stamps, a.refused) == (b.z, b.y, b.stamps, b.refused)
        assert a.z != [NONE] * len(p.tasks)  # the good message was applied
        assert sum(a.refused.values()) == 1  # the bad one refused whole
