"""SSI after a team apart (issue 49, w23): the auctioneer stood still past `progress_timeout`,
its teammates followed the next id, and came back with tasks it never awarded — an honest
served report that a third robot's Round backs is believed (robot_agent/ssi/auction.py, "What
a message is believed for"; docs/security.md). The logics on the in-process exchange
(tests/harness/logic_team.py)."""

from __future__ import annotations

from mrta_agent.ssi.auction import NOT_HELD
from mrta_agent.ssi.messages import DONE, Bid
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.test_believed_claims import allocated, refused, ssi_team


APART = Problem((Robot("r1", (0.0, 0.0), 1.0), Robot("r2", (20.0, 0.0), 1.0),
                 Robot("r3", (4.0, 0.0), 1.0)),
                (Task("a", (1.0, 0.0)), Task("b", (21.0, 0.0)), Task("c", (5.0, 0.0)),
                 Task("d", (22.0, 0.0), arrival=12.0)))  # a reason for r1 to open a round


def test_a_task_served_under_a_team_apart_is_believed_when_the_auctioneer_is_back():
    """r2 and r3 count the auctioneer r1 out (it stood still past `progress_timeout`: a stall
    it does not know of), r2 leads them and awards r1's task `a` to r3, which serves it; once
    they count r1 back, r3 reports `a` to r1 — which never awarded it to r3 and refused it as
    forged, every `resend_period` (w23: TeSSI on Solomon's C109, 200 refusals). r2's Rounds,
    heard by r1 meanwhile, showed r3 holding it: believed. A claim only the claimant's own
    Round showed is refused, but not counted forged."""
    team = ssi_team(APART)
    team.run()
    assert allocated(team) == {"a": "r1", "b": "r2", "c": "r3"} and team.now < 5.0
    for robot in ("r2", "r3"):
        team.logics[robot].teammate("r1", False)
    team.run(until=team.now + 3.0)
    assert team.now < 12.0
    a = APART.task_index("a")
    assert team.logics["r2"].owners[a] == APART.robot_index("r3")  # r1's task, awarded apart
    team.logics["r3"].served("a", team.now)
    for robot in ("r2", "r3"):
        team.logics[robot].teammate("r1", True)
    team.run(until=15.0)
    r1 = team.logics["r1"]
    assert r1.owners[a] == DONE and refused([r1], NOT_HELD) == 0
    # a task only the claimant's own Round showed it holding (as r2's own award to itself
    # while it led would be): refused, not counted forged
    c, r2 = APART.task_index("c"), APART.robot_index("r2")
    r1.shown[(r2, c)] = {r2}
    claim = Bid(Header("r2", team.now, 999), "r1", r1.round, -1, 0.0, (c,), 0.0)
    assert team.deliver("r1", "bid", claim)
    assert r1.refused[("bid", "r2", NOT_HELD, False)] == 1 and r1.owners[c] != DONE
