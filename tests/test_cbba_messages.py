"""CBBA on the bus: its message on the wire (small, strict), what a robot does with a malformed,
late or out-of-range message, served tasks, moving its origin, and a team ticking
asynchronously in virtual time (tests/harness/logic_team.py) under message loss, which still ends as the
sequential greedy assignment (tests/harness/cbba_reference.py)."""

from __future__ import annotations

import math
import random

import pytest

from mrta_agent.cbba.bundle import Cbba
from mrta_agent.cbba.messages import MESSAGES, Bids
from mrta_agent.cbba.synchronous import run_rounds
from mrta_zenoh.codec import decode, encode
from mrta_zenoh.instances import DIGEST_LENGTH
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from mrta_zenoh.planning.insertion import Origin
from tests.harness.cbba_reference import greedy, random_instance
from tests.harness.logic_team import LogicTeam


def two_robots(gap: float = 10.0) -> Problem:
    return Problem((Robot("r1", (0.0, 0.0), 1.0), Robot("r2", (gap, 0.0), 1.0)),
                   (Task("a", (1.0, 0.0)), Task("b", (gap - 1.0, 0.0)), Task("c", (gap / 2, 3.0))))


def bids(sender="r2", stamp=1.0, winners=(), stamps=(), done=(), at=(10.0, 0.0)) -> Bids:
    return Bids(Header(sender, stamp, 1), tuple(winners), tuple(stamps), tuple(done), *at)


def test_the_message_round_trips_and_grows_with_tasks_won_not_with_the_instance():
    msg = bids(winners=[(0, 1, 0.5), (7, 0, 0.25)], stamps=[(0, 1.0), (1, 1.0)], done=[3])
    assert decode(msg.TYPE_NAME, encode(msg)) == msg
    empty = len(encode(bids(stamps=[(0, 1.0), (1, 1.0)])))
    one = len(encode(bids(winners=[(0, 1, 0.5)], stamps=[(0, 1.0), (1, 1.0)])))
    # a winner entry: three numbers (task, robot: one byte each below 128; bid: 9 bytes)
    assert one - empty <= 12
    rng = random.Random(0)
    p = Problem(tuple(Robot(f"r{i}", (rng.uniform(0, 50), rng.uniform(0, 50)), 1.0)
                      for i in range(10)),
                tuple(Task(f"t{j}", (rng.uniform(0, 50), rng.uniform(0, 50))) for j in range(60)))
    team = {r.id: Cbba(p, r.id, resend_period=0.0, bundle_limit=6) for r in p.robots}
    run_rounds(team)
    fields = team["r0"].tick(1000.0)[0].fields
    digest = "0" * DIGEST_LENGTH
    size = len(encode(Bids(header=Header("r0", 1000.0, 1), **fields, instance=digest)))
    base = len(encode(Bids(header=Header("r0", 1000.0, 1), **{**fields, "winners": ()},
                           instance=digest)))
    assert len(fields["winners"]) == 60 and len(fields["stamps"]) == 10  # every task won,
    # every robot heard
    assert size - base <= 12 * 60 + 2  # + a longer array header past 15 entries
    # header, stamps of 10 robots, position, the decision's ms, the instance's digest (27 bytes)
    assert base <= 239


def test_a_malformed_message_is_refused_whole():
    p = two_robots()
    logic = Cbba(p, "r1")
    logic.tick(0.0)
    before = (list(logic.z), list(logic.y), dict(logic.stamps))
    # task 3 of 3: taken for a task submitted at run time this robot has not taken yet (out
    # of lockstep the change may reach it later) — dropped, counted, not as forged
    assert logic.hear("bids", "r2", bids(winners=[(0, 1, 0.9), (3, 1, 0.9)]), 1.0)
    assert logic.refused[("bids", "r2", "tasks_ahead", False)] == 1
    for bad in (bids(winners=[(0, 1, 0.9), (3 + 100_000, 1, 0.9)]),  # beyond any run's tasks
                bids(winners=[(0, 5, 0.9)]),                 # robot 5 of 2
                bids(stamps=[(2, 1.0)]),
                bids(done=[-1])):
        assert not logic.hear("bids", "r2", bad, 1.0)
    assert not logic.hear("bids", "stranger", bids(), 1.0)
    assert not logic.hear("bids", "r1", bids(sender="r1"), 1.0)  # its own
    assert (list(logic.z), list(logic.y), dict(logic.stamps)) == before


def test_a_message_older_than_one_applied_is_superseded():
    p = two_robots()
    logic = Cbba(p, "r1", lookahead=math.inf)
    logic.tick(0.0)
    newer = bids(stamp=5.0, winners=[(2, 1, 0.9)], stamps=[(1, 5.0)])
    older = bids(stamp=4.0, winners=[], stamps=[(1, 4.0)])  # r2 once held nothing
    assert logic.hear("bids", "r2", newer, 5.0)
    assert logic.z[2] == 1
    assert logic.hear("bids", "r2", older, 5.5)
    assert logic.z[2] == 1 and logic.superseded == 1  # row 15 would have reset it


def test_out_of_range_robots_do_not_hear_each_other():
    p = two_robots(gap=100.0)
    near = {r.id: Cbba(p, r.id, resend_period=0.0, comm_range=200.0) for r in p.robots}
    run_rounds(near)
    assert near["r1"].z == near["r2"].z and near["r1"].out_of_range == 0
    far = {r.id: Cbba(p, r.id, resend_period=0.0, comm_range=50.0) for r in p.robots}
    run_rounds(far)
    assert far["r1"].out_of_range > 0
    # each allocates alone: c, halfway, is in both bundles — the fault's conflict
    assert 2 in far["r1"].bundle and 2 in far["r2"].bundle
    assert far["r1"].z[2] == 0 and far["r2"].z[2] == 1


def test_a_served_task_leaves_every_bundle_for_good_and_the_route_starts_there():
    p = two_robots()
    team = {r.id: Cbba(p, r.id, resend_period=0.0) for r in p.robots}
    last = run_rounds(team)
    first = team["r1"].path[0]
    served = p.tasks[first].id
    team["r1"].served(served, 2.0)
    assert team["r1"].origin == (first, 2.0) and team["r1"].position == p.tasks[first].position
    run_rounds(team, start=last + 1)
    for logic in team.values():
        assert first in logic.done and first not in logic.bundle
        assert served not in logic.winners()
    assert team["r1"].active_task != served


def test_relocating_counts_every_score_from_the_new_origin():
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), (Task("a", (3.0, 4.0)), Task("b", (6.0, 8.0))))
    logic = Cbba(p, "r", bundle_limit=1)
    logic.tick(0.0)
    assert logic.bundle == [0] and logic.y[0] == 0.95 ** 5
    logic.relocate(Origin(None, 40.0))  # idle at its start until 40 s
    logic.tick(40.0)
    assert logic.y[0] == 0.95 ** 5  # its bid stands: still the greedy choice
    logic.bundle_limit = 2
    logic.tick(40.1)
    assert logic.bundle == [0, 1] and logic.y[1] == pytest.approx(0.95 ** 50)  # 40 + 5 + 5


def test_a_team_ticking_in_virtual_time_under_loss_still_ends_as_the_greedy_assignment():
    # not the paper's synchronous rounds: each robot ticks every 0.1 s, hears what the others
    # said a tick before, 30 % of messages are lost and the state is repeated every 0.5 s
    rng = random.Random(7)
    for seed in range(10):
        p = random_instance(rng, rng.randint(2, 5), rng.randint(3, 9))
        team = LogicTeam({r.id: Cbba(p, r.id, resend_period=0.5, lookahead=math.inf)
                          for r in p.robots}, MESSAGES, loss=0.3, seed=seed)
        team.run(quiet=1, until=40.0)  # resends never stop: run on time
        assert team.dropped > 0
        views = {tuple(logic.z) for logic in team.logics.values()}
        assert len(views) == 1
        assert {p.robot_index(r): logic.path for r, logic in team.logics.items()} == greedy(p)[0]


def test_bad_parameters_are_refused():
    p = two_robots()
    with pytest.raises(ValueError, match="discount"):
        Cbba(p, "r1", discount=1.5)
    with pytest.raises(ValueError, match="bundle limit"):
        Cbba(p, "r1", bundle_limit=0)
    with pytest.raises(KeyError):
        Cbba(p, "r9")


def test_a_bids_after_a_change_carries_its_decisions_cost_and_a_resend_none():
    """CBBA's decision (architecture.decision): the bundle work that changed a robot's table,
    its wall time in `Bids.ms`; a periodic resend of an unchanged table records none."""
    from mrta_agent.cbba.architecture import CBBA
    p = two_robots()
    logic = Cbba(p, "r1", resend_period=1.0)
    first = logic.tick(0.0)[0].fields
    assert first["ms"] > 0.0  # it built its first bundle
    assert logic.tick(0.5) == []  # nothing changed, not due
    again = logic.tick(1.5)[0].fields  # the periodic resend of the same table
    assert again["winners"] == first["winners"] and again["ms"] == 0.0  # stamps move on
    sent = Bids(header=Header("r1", 0.0, 1), **first)
    d = CBBA.decision("r1", "r1/cbba/bids", sent)
    assert d is not None and d.ms == first["ms"] and d.decider == "r1"
    resent = CBBA.decision("r1", "r1/cbba/bids", Bids(header=Header("r1", 1.5, 2), **again))
    assert not resent.counted  # read only for whom it counts out (Bids.out)
    # what a run's summary counts from the recording (supervisor/ground_truth.decisions)
    from mrta_supervisor.mission.ground_truth import decisions
    from mrta_zenoh.codec import encode
    enc = "application/msgpack;" + Bids.TYPE_NAME
    records = [("r1/cbba/bids", enc, 0, encode(sent)),
               ("r1/cbba/bids", enc, 0, encode(Bids(header=Header("r1", 1.5, 2), **again)))]
    summary = decisions(records, CBBA, end=10.0)
    assert (summary.count, summary.max_ms) == (1, round(first["ms"], 3))
