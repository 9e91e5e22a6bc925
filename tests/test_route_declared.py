"""SSI's and CBBA's declared stalls in the summary (issue 51.2; central's were already there): a
robot whose reports show no progress for `progress_timeout` is counted out by its teammates
(robot_agent/route/own_route.py), SSI's auctioneer leaves out one that stops answering its
rounds — and the run's summary names who declared whom, why, from when until when
(`decisions.declared`), read from the messages the architectures already send (SSI's `Round`,
CBBA's `Bids`). A team on the in-process exchange (tests/harness/route_team.py), its messages
fed to the summary's reader as a recording would hold them."""

from __future__ import annotations

from mrta_agent.cbba.agent import CbbaCoordinator
from mrta_agent.cbba.architecture import CBBA
from mrta_agent.cbba.params import CbbaKeys
from mrta_agent.ssi.agent import SsiCoordinator
from mrta_agent.ssi.architecture import SSI
from mrta_agent.ssi.auction import Ssi
from mrta_agent.ssi.messages import Bid
from mrta_agent.ssi.params import SsiKeys
from mrta_supervisor.mission.ground_truth import decisions
from mrta_zenoh.codec import encode
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.route_team import RouteTeam, params_for

TIMEOUT = 5.0
LINE = Problem((Robot("robot1", (0.0, 0.0), 1.0), Robot("robot2", (20.0, 0.0), 1.0),
                Robot("robot3", (10.0, 5.0), 1.0)),
               (Task("t1", (2.0, 0.0), service=1.0), Task("t2", (18.0, 0.0), service=1.0),
                Task("t3", (15.0, 0.0), service=1.0), Task("t4", (10.0, 8.0), service=1.0)))


def recording(t: RouteTeam, arch) -> list:
    return [(f"{msg.header.frame_id}/{arch.namespace}/{kind}", "application/msgpack;"
             + type(msg).TYPE_NAME, 0, encode(msg)) for kind, msg in t.sent]


def stalled_run(arch, make) -> tuple[RouteTeam, float]:
    t = RouteTeam(LINE, arch.messages, make)
    while t.coords["robot2"].route.current is None:
        assert t.now < 60.0
        t.step()
    stalled_at = t.now
    t.stall("robot2")
    t.run_until_served()
    return t, stalled_at


def test_an_ssi_stall_is_named_in_the_summary_by_the_auctioneer_with_its_instant():
    t, stalled_at = stalled_run(SSI, lambda rid, body: SsiCoordinator(
        rid, params_for(LINE, SsiKeys(), TIMEOUT), body))
    found = decisions(recording(t, SSI), SSI, end=t.now)
    mine = [d for d in found.declared if d.robot == "robot2"]
    assert [(d.reason, d.by) for d in mine] == [("stalled", "robot1")], found.declared
    assert stalled_at + TIMEOUT <= mine[0].at <= stalled_at + TIMEOUT + 1.5  # its reports lag
    assert mine[0].until is None  # it never moved again
    # every award is still one decision: the Rounds that only say who is out are not counted
    awards = {m.round for k, m in t.sent if k == "round" and m.award >= 0}
    assert found.count == len(awards)


def test_a_cbba_stall_is_named_in_the_summary_by_every_teammate_with_its_instant():
    t, stalled_at = stalled_run(CBBA, lambda rid, body: CbbaCoordinator(
        rid, params_for(LINE, CbbaKeys(), TIMEOUT), body))
    found = decisions(recording(t, CBBA), CBBA, end=t.now)
    mine = sorted((d.by, d.reason) for d in found.declared if d.robot == "robot2")
    assert mine == [("robot1", "stalled"), ("robot3", "stalled")], found.declared
    for d in found.declared:
        assert stalled_at + TIMEOUT <= d.at <= stalled_at + TIMEOUT + 1.5 and d.until is None
    assert found.count == sum(1 for k, m in t.sent if k == "bids" and m.ms > 0.0)


def test_the_auctioneer_names_a_robot_that_stops_answering_silent_and_back_when_it_bids():
    """robot2's token lives but it never bids (a forger keeps a dead robot's token alive): the
    rounds leave it out after `silence` and say so; its first bid ends the stretch."""
    a = Ssi(LINE, "robot1", silence=3.0, join_wait=0.0)
    for r in ("robot2", "robot3"):
        a.teammate(r, True)
    said = [s for now in (0.0, 1.0, 2.0, 3.5) for s in a.tick(now)]
    assert said[-1].fields["out"] == ("robot2:silent", "robot3:silent")
    assert all(s.fields["out"] == () for s in said[:-1])
    bid = Bid(Header("robot2", 3.6, 1), "robot1", a.round, -1, 0.0, ())
    assert a.hear("bid", "robot2", bid, 3.6)
    (again,) = a.tick(3.7)  # said at once: who is out changed
    assert again.fields["out"] == ("robot3:silent",)
