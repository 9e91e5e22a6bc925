"""CBBA under partial connectivity: what an honest robot of a team cut into groups says of a
task served is not called forged (the study's file 07, delivery under `range:4`: 9 of 30 CBBA
runs were `disturbed` by robot5 refusing its honest teammates' `done` as `done_not_won` and
`done_too_early`), while a claim its own sender contradicts still is (docs/security.md).

A team of real logics in virtual time (tests/harness/logic_team.py) whose links change at set
times — what the range fault does as robots move, reduced to who hears whom: r1 (0, 0) and r3
(20, 0) never hear each other, r2 sits between; task a (1, 0) is r1's to serve."""

from __future__ import annotations

import math

from mrta_agent.cbba.bundle import CLAIM_SLACK, NOT_WON, TOO_EARLY, UNCONFIRMED, Cbba
from mrta_agent.cbba.messages import MESSAGES, Bids
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.logic_team import LogicTeam

A = 0  # task a's index


def team_linked(r2: tuple[float, float], links, r2_lifts: bool = True) -> LogicTeam:
    """r1, r2 (at `r2`), r3 on a line, task a next to r1 (a lift: r2 can serve it only if
    `r2_lifts`); `links(now)`: the pairs that hear each other at `now`."""
    lift = frozenset({"lift"})
    p = Problem((Robot("r1", (0.0, 0.0), 1.0, lift),
                 Robot("r2", r2, 1.0, lift if r2_lifts else frozenset()),
                 Robot("r3", (20.0, 0.0), 1.0, lift)),
                (Task("a", (1.0, 0.0), capability="lift"),))
    team = LogicTeam({r.id: Cbba(p, r.id, lookahead=math.inf, resend_period=1.0)
                      for r in p.robots}, MESSAGES,
                     neighbours=lambda x, y: frozenset((x, y)) in links(team.now))
    return team


def forged(logic: Cbba) -> list:
    return [e for e, n in logic.refused.items() if e[3] and n]


R12, R23 = frozenset(("r1", "r2")), frozenset(("r2", "r3"))


def test_a_relay_of_a_service_the_receiver_learns_of_late_is_not_called_forged():
    """r3, out of everyone's range, bids a and goes for it; r1 serves it at 2 s and r2 hears
    so; from 10 s r2 is within r3's range and says a served — r3 never heard r1 win it, so the
    claim waits (unconfirmed), and r3 serves a itself at 25 s. That claim came 15 s before r3
    knew a served, and was refused as forged (`done_not_won`): robot5's refusal of robot2 in
    delivery-r5-t5-2."""
    team = team_linked((2.0, 0.0), lambda now: {R12} if now < 10.0 else {R12, R23})
    r1, r2, r3 = (team.logics[r] for r in ("r1", "r2", "r3"))
    team.run(until=2.0)
    assert r1.bundle == [A] and r3.bundle == [A]  # both believe they won a
    r1.served("a", team.now)
    team.run(until=12.0)
    assert A in r2.done and A not in r3.done and r3.bundle == [A]
    assert r3.refused[("bids", "r2", UNCONFIRMED, False)] == 1
    team.run(until=25.0)
    r3.served("a", team.now)
    team.run()
    assert A in r3.done and not r3.done_claims
    assert not forged(r3), r3.refused
    assert not r3.refused[("bids", "r2", UNCONFIRMED, False)]


def test_a_former_winner_relaying_a_service_by_a_robot_the_receiver_never_heard_win_is_waited_on():
    """r2 (12, 0) bids a where r3 hears it, then, cut off from r3, loses it to r1 and hears r1
    serve it at 3 s; back in r3's range at 6 s it says a served — too early for r2 (11 s from
    its start), and r3 never heard r1 win a (`done_too_early`: robot5's refusal of robot1 in
    delivery-r5-t5-4). r2's time stamps show news from r1 from 3 s, when r1 could have served
    a: a relay, which waits like any other."""
    def links(now: float) -> set:
        return {R23} if now < 2.0 or now >= 6.0 else {R12}
    team = team_linked((12.0, 0.0), links)
    r1, r2, r3 = (team.logics[r] for r in ("r1", "r2", "r3"))
    team.run(until=2.0)
    assert r3.won[A] == {1, 2} and r3.z[A] == 1  # r3 believes r2 won a
    team.run(until=3.0)
    assert r1.bundle == [A] and r2.z[A] == 0
    r1.served("a", team.now)
    team.run(until=6.0)
    assert A in r2.done and r3.earliest(1, A) - CLAIM_SLACK > 6.0
    team.run(until=8.0)
    assert A not in r3.done and r3.refused[("bids", "r2", UNCONFIRMED, False)] == 1
    assert not forged(r3), r3.refused
    team.run(until=25.0)
    r3.served("a", team.now)
    team.run()
    assert not forged(r3), r3.refused


def test_a_claim_its_sender_then_leaves_out_is_forged_under_a_range_too():
    """What the range does not excuse: a `done` under r2's key (r2 cannot serve a) that r2's own
    next message does not repeat was not r2's — a robot's served tasks only grow — and is
    refused as forged once the task is served, here by the receiver itself."""
    team = team_linked((2.0, 0.0), lambda now: {R12, R23}, r2_lifts=False)
    r3 = team.logics["r3"]
    team.run(until=2.0)
    assert r3.z[A] == 0 and 1 not in r3.won[A]
    claim = Bids(Header("r2", team.now, 99), (), ((1, team.now),), (A,), 2.0, 0.0)
    assert team.deliver("r3", "bids", claim) and A not in r3.done
    team.run(until=5.0)
    assert not forged(r3) and (1, A) in r3.contradicted  # judged once a is served
    r3.served("a", team.now)
    assert forged(r3) == [("bids", "r2", NOT_WON, True)]


def test_a_claim_no_robot_its_sender_heard_of_could_have_made_is_still_too_early():
    """A known winner's `done` before it, or any robot its time stamps name, could have served
    the task stays forged (`done_too_early`), partition or not."""
    team = team_linked((12.0, 0.0), lambda now: {R23})
    r3 = team.logics["r3"]
    team.run(until=2.0)
    assert 1 in r3.won[A]
    at_once = Bids(Header("r2", team.now, 99), (), ((1, team.now), (2, team.now)), (A,), 12.0,
                   0.0)
    assert team.deliver("r3", "bids", at_once)
    assert A not in r3.done and forged(r3) == [("bids", "r2", TOO_EARLY, True)]
