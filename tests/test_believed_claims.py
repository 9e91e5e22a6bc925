"""SSI and CBBA believe a message only for what its sender can claim (issue 51; the module
docstrings of mrta_agent.ssi.auction and mrta_agent.cbba.bundle, docs/security.md): each rule
forges the message the hostile probe sent — once, on a team of real logics exchanging real
messages in virtual time (tests/harness/logic_team.py) — and checks that the team still allocates every
task, and that the forgery was counted."""

from __future__ import annotations

import math

from mrta_agent.cbba.bundle import (BID_OUT_OF_RANGE, NOT_WON, STAMP_AHEAD, TOO_EARLY,
                                    UNCONFIRMED, Cbba)
from mrta_agent.cbba.messages import MESSAGES as CBBA_MESSAGES, Bids
from mrta_agent.ssi.auction import (CANNOT_SERVE, NEGATIVE_COST, NOT_HELD, ROUND_AHEAD,
                                    ROUND_NOT_SENT, Ssi)
from mrta_agent.ssi.messages import MESSAGES as SSI_MESSAGES, DONE, OPEN, Bid, Round
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.logic_team import LogicTeam

LINE = Problem((Robot("r1", (0.0, 0.0), 1.0), Robot("r2", (5.0, 0.0), 1.0),
                Robot("r3", (10.0, 0.0), 1.0, frozenset({"lift"}))),
               (Task("a", (3.0, 0.0)), Task("b", (7.0, 0.0)), Task("c", (12.0, 0.0)),
                Task("d", (9.0, 0.0), capability="lift")))


def refused(logics, reason: str) -> int:
    return sum(n for logic in logics for (_k, _s, r, _f), n in logic.refused.items()
               if r == reason)


# ------------------------------------------------------------------ SSI
def ssi_team(p: Problem = LINE, **kw) -> LogicTeam:
    kw.setdefault("join_wait", 0.0)
    return LogicTeam({r.id: Ssi(p, r.id, **kw) for r in p.robots}, SSI_MESSAGES)


def allocated(team: LogicTeam) -> dict[str, str]:
    return next(iter(team.logics.values())).winners()


def test_a_round_numbered_2_62_from_the_auctioneers_key_does_not_stop_the_auction():
    """Said once to every bidder before the first real Round: today's rule (adopt any round not
    lower than the last) made every real round look old, and nothing was ever awarded."""
    team = ssi_team()
    forged = Round(Header("r1", 0.0, 99), 2 ** 62, (OPEN,) * 4, -1, 0.0)
    for robot in ("r2", "r3"):
        assert team.deliver(robot, "round", forged)
    team.run()
    assert sorted(allocated(team)) == ["a", "b", "c", "d"]
    assert {tuple(logic.owners) for logic in team.logics.values()} == {
        tuple(team.logics["r1"].owners)}
    assert refused(team.logics.values(), ROUND_AHEAD) == 2


def test_a_round_far_ahead_repeated_by_the_auctioneer_is_believed():
    """A robot that missed many rounds (a partition) is not locked out: the auctioneer repeats
    its Round until answered, and the repeat confirms it."""
    s = Ssi(LINE, "r2", resend_period=0.5)
    s.teammate("r1", True)
    far = Round(Header("r1", 1.0, 7), 500, (0, OPEN, OPEN, OPEN), 0, 3.0)
    assert s.hear("round", "r1", far, 1.0) and s.round == 0
    assert s.hear("round", "r1", far, 1.1) and s.round == 0   # at once: no confirmation
    assert s.hear("round", "r1", far, 1.6) and s.round == 500


def test_a_round_the_auctioneer_never_sent_does_not_empty_the_paths_once_the_auction_is_over():
    """A Round under the auctioneer's key, said once to every bidder after the last award, of
    the same number or the next, saying every task DONE: the bidders adopted it and emptied
    their paths, and the auctioneer — every bid in, nothing open — never said anything again:
    no task served, for good. Each bid now names the Round it answers; the auctioneer repeats
    its own until they answer it, and counts the bids (`round_not_sent`)."""
    for ahead in (0, 1):
        team = ssi_team()
        team.run()
        routes = {r: logic.route() for r, logic in team.logics.items()}
        number = team.logics["r1"].round + ahead
        forged = Round(Header("r1", team.now, 99), number, (DONE,) * 4, -1, 0.0)
        for robot in ("r2", "r3"):
            assert team.deliver(robot, "round", forged)
            assert team.logics[robot].route() == []  # believed: it is the auctioneer's key
        team.run(until=team.now + 5.0)
        assert {r: logic.route() for r, logic in team.logics.items()} == routes
        assert refused([team.logics["r1"]], ROUND_NOT_SENT) == 2


def test_a_bids_computation_time_counts_at_most_the_wall_time_since_its_round_went_out():
    """A bidder measures its own bid, and the slowest bid is the round's decision time: a
    forged Bid saying 1e300 ms made it the run's. Believed up to the auctioneer's wall time
    since it sent the round."""
    wall = [100.0]
    s = Ssi(LINE, "r1", timer=lambda: wall[0])
    s.teammate("r2", True)
    s.tick(0.0)  # r1 leads: round 1 goes out at wall 100.0
    wall[0] = 100.5
    assert s.hear("bid", "r2", Bid(Header("r2", 0.1, 1), "r1", s.round, 0, 1.0, (), 1e300), 0.1)
    assert s.bid_ms[1] == 500.0
    assert s.hear("bid", "r2", Bid(Header("r2", 0.1, 2), "r1", s.round, 0, 1.0, (), 20.0), 0.1)
    assert s.bid_ms[1] == 20.0


def test_a_bid_reporting_every_task_served_counts_only_for_the_tasks_its_bidder_held():
    team = ssi_team()
    team.run()
    before = allocated(team)
    held_by_r2 = [LINE.task_index(t) for t, r in before.items() if r == "r2"]
    forged = Bid(Header("r2", team.now, 99), "r1", team.logics["r1"].round, -1, 0.0,
                 (0, 1, 2, 3), 0.0)
    assert team.deliver("r1", "bid", forged)
    team.run()
    owners = team.logics["r1"].owners
    done = [j for j, w in enumerate(owners) if w < 0 and w != OPEN]
    assert sorted(done) == sorted(held_by_r2)  # only r2's own are DONE; the others still owned
    assert refused([team.logics["r1"]], NOT_HELD) == 4 - len(held_by_r2)


def test_a_bid_at_a_negative_cost_or_for_a_task_its_bidder_cannot_serve_is_refused():
    s = Ssi(LINE, "r1")
    s.teammate("r2", True)
    s.teammate("r3", True)
    s.tick(0.0)  # r1 leads: round 1 opens
    assert s.hear("bid", "r2", Bid(Header("r2", 0.1, 1), "r1", s.round, 0, -5.0, (), 0.0), 0.1)
    assert s.hear("bid", "r2", Bid(Header("r2", 0.1, 2), "r1", s.round, 3, 0.1, (), 0.0), 0.1)
    assert 1 not in s.bids and refused([s], NEGATIVE_COST) == 1 \
        and refused([s], CANNOT_SERVE) == 1


def test_the_auctioneer_leaves_out_a_robot_that_does_not_answer_and_gives_its_tasks_away():
    """r3's token lives (a forger keeps it, or r3 is a certified robot that never bids) but r3
    never answers: the round waited for it for ever; now it waits `silence` seconds."""
    p = Problem(LINE.robots, LINE.tasks[:3])
    team = LogicTeam({r: Ssi(p, r, join_wait=0.0, silence=5.0) for r in ("r1", "r2")},
                     SSI_MESSAGES)
    for logic in team.logics.values():
        logic.teammate("r3", True)
    team.run(until=8.0)
    assert sorted(allocated(team)) == ["a", "b", "c"]
    assert set(allocated(team).values()) <= {"r1", "r2"}
    assert 2 in team.logics["r1"].silent


# ------------------------------------------------------------------ CBBA
def cbba_team(p: Problem = LINE) -> LogicTeam:
    return LogicTeam({r.id: Cbba(p, r.id, lookahead=math.inf, resend_period=1.0)
                      for r in p.robots}, CBBA_MESSAGES)


def test_a_bids_saying_every_task_done_from_a_robot_that_won_none_of_them_is_not_believed():
    """Not believed alone (it waits, unconfirmed); once the tasks are really served, the claim
    made long before is refused as forged — by each robot it was told to, once per task."""
    team = cbba_team()
    forged = Bids(Header("r3", 0.0, 99), (), ((2, 0.0),), (0, 1, 2, 3), 10.0, 0.0)
    for robot in ("r1", "r2"):
        assert team.deliver(robot, "bids", forged)
    team.run()
    for logic in team.logics.values():
        assert not logic.done
    won = {j for logic in team.logics.values() for j in logic.bundle}
    assert won == {0, 1, 2, 3}
    assert refused(team.logics.values(), UNCONFIRMED) == 8 and not refused(
        team.logics.values(), NOT_WON)
    team.run(until=team.now + 30.0)  # every winner could have served its tasks by then
    for logic in team.logics.values():
        for j in list(logic.bundle):
            logic.served(LINE.tasks[j].id, team.now)
    team.run()
    assert all(logic.done == {0, 1, 2, 3} for logic in team.logics.values())
    assert refused(team.logics.values(), NOT_WON) == 8  # 4 tasks, told to 2 robots
    assert not refused(team.logics.values(), UNCONFIRMED)


def test_a_relayed_done_to_a_robot_that_missed_who_won_is_not_called_forged():
    """The golden cbba-stall run: the stalled robot1 still believes it won t1 when robot3,
    which took it over, and then the others say it served. Those claims are honest: once a
    majority says so the task is done, and nothing is counted as forged (it was, as
    `done_not_won`, making the run `disturbed`)."""
    r1 = Cbba(LINE, "r1", lookahead=math.inf, resend_period=1.0)
    for other in ("r2", "r3"):
        r1.teammate(other, True)
    r1.tick(0.0)
    j = r1.bundle[0]
    assert r1.z[j] == 0
    served = Bids(Header("r2", 40.0, 50), (), ((1, 40.0),), (j,), 12.0, 0.0)
    relayed = Bids(Header("r3", 40.1, 50), (), ((2, 40.1),), (j,), 10.0, 0.0)
    assert r1.hear("bids", "r2", served, 40.0) and j not in r1.done  # one claim: not yet
    assert r1.hear("bids", "r3", relayed, 40.1)
    assert j in r1.done
    assert not [e for e in r1.refused if e[3]], r1.refused


def test_a_winner_saying_its_task_served_before_it_could_have_reached_it_is_not_believed():
    """A certified robot saying a task it won served at once (docs/security.md): believed
    only from when it could have served it — from its start, at its speed."""
    r1 = Cbba(LINE, "r1", lookahead=math.inf, resend_period=1.0)
    for other in ("r2", "r3"):
        r1.teammate(other, True)
    c = 2  # (12, 0): r2, from (5, 0) at 1 m/s, reaches it at 7 s at the earliest
    assert r1.earliest(1, c) == 7.0
    bid = Bids(Header("r2", 0.1, 1), ((c, 1, 0.9),), ((1, 0.1),), (), 5.0, 0.0)
    assert r1.hear("bids", "r2", bid, 0.1) and r1.z[c] == 1
    at_once = Bids(Header("r2", 0.2, 2), (), ((1, 0.2),), (c,), 12.0, 0.0)
    assert r1.hear("bids", "r2", at_once, 0.2)
    assert c not in r1.done and refused([r1], TOO_EARLY) == 1
    later = Bids(Header("r2", 7.5, 3), (), ((1, 7.5),), (c,), 12.0, 0.0)
    assert r1.hear("bids", "r2", later, 7.5) and c in r1.done
    assert refused([r1], TOO_EARLY) == 1


def test_a_former_winner_relaying_the_new_winners_service_is_not_called_a_forger():
    """After a partition (the study's file 04, CBBA, instance 3): r2 won c, lost it to r3 on its
    side, and reports r3's service as soon as it rejoins — too early for r2 to have served c,
    not for r3. A relay, so it goes the way of relays (a majority), never counted forged."""
    r1 = Cbba(LINE, "r1", lookahead=math.inf, resend_period=1.0)
    for other in ("r2", "r3"):
        r1.teammate(other, True)
    c = 2  # (12, 0): r2 (from (5, 0)) reaches it at 7 s at the earliest, r3 (from (10, 0)) at 2 s
    assert r1.earliest(1, c) == 7.0 and r1.earliest(2, c) < 4.0
    r1.hear("bids", "r2", Bids(Header("r2", 0.1, 1), ((c, 1, 0.9),), ((1, 0.1),), (), 5.0, 0.0), 0.1)
    r1.hear("bids", "r3", Bids(Header("r3", 0.2, 1), ((c, 2, 0.95),), ((2, 0.2),), (), 5.0, 0.0), 0.2)
    assert r1.won[c] == {1, 2}
    relay = Bids(Header("r2", 3.5, 2), (), ((1, 3.5),), (c,), 12.0, 0.0)  # 7 s − 3.5 > CLAIM_SLACK
    assert r1.hear("bids", "r2", relay, 3.5)
    assert refused([r1], TOO_EARLY) == 0 and not [e for e in r1.refused if e[3]], r1.refused


def test_a_bids_with_a_winning_bid_above_the_tasks_reward_is_refused_whole():
    team = cbba_team()
    forged = Bids(Header("r3", 0.0, 99), ((0, 2, 1e9), (1, 2, 1e9)), ((2, 0.0),), (), 10.0, 0.0)
    assert team.deliver("r1", "bids", forged)
    assert team.logics["r1"].z[0] != 2 and refused([team.logics["r1"]], BID_OUT_OF_RANGE) == 1


def test_a_bids_stamped_far_ahead_is_refused_and_does_not_silence_its_sender():
    """Out of lockstep a message counts as heard now; one stamped an hour ahead made every real
    message of its sender look older ("superseded") until then."""
    team = cbba_team()
    forged = Bids(Header("r3", 3600.0, 99), (), ((2, 3600.0),), (), 10.0, 0.0)
    assert team.logics["r1"].hear("bids", "r3", forged, 0.0)  # heard at 0
    assert refused([team.logics["r1"]], "stamp_ahead") == 1
    team.run()
    assert {j for logic in team.logics.values() for j in logic.bundle} == {0, 1, 2, 3}
    assert team.logics["r1"].superseded == 0


def test_a_bids_with_time_stamps_from_the_future_is_refused():
    """A Bids (under r2's key, to r1 and r3, which hear each other only through r2: a range)
    stamping every robot 10^12: each receiver's time stamps froze there, no relay was newer
    ever again, and r1 kept b and c, which r3 had won — both served them. An entry later than
    the message itself (by more than the clock slack) is refused whole (`stamp_ahead`)."""
    def chain() -> LogicTeam:
        return LogicTeam({r.id: Cbba(LINE, r.id, lookahead=math.inf, resend_period=1.0)
                          for r in LINE.robots}, CBBA_MESSAGES,
                         neighbours=lambda a, b: {a, b} != {"r1", "r3"})
    honest = chain()
    honest.run()
    team = chain()
    forged = Bids(Header("r2", 0.0, 99), (), ((0, 1e12), (1, 1e12), (2, 1e12)), (), 5.0, 0.0)
    for robot in ("r1", "r3"):
        assert team.deliver(robot, "bids", forged)
    team.run()
    assert {r: logic.route() for r, logic in team.logics.items()} == \
        {r: logic.route() for r, logic in honest.logics.items()}
    assert refused(team.logics.values(), STAMP_AHEAD) == 2

