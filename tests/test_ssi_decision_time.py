"""SSI's decision time (robot_agent/ssi/auction.py, "Decision time"): every award carries its
computation time — the slowest bid of its round plus the winner determination — and a run's
records yield one decision per award, with those times, however often a Round was repeated."""

from __future__ import annotations

from mrta_agent.ssi.agent import SsiCoordinator
from mrta_agent.ssi.architecture import SSI
from mrta_agent.ssi.auction import Ssi
from mrta_agent.ssi.messages import MESSAGES, Round
from mrta_agent.ssi.params import SsiKeys
from mrta_zenoh.codec import encode, encoding_for
from mrta_zenoh.messages import Header
from mrta_supervisor.mission.ground_truth import decisions
from tests.harness.logic_team import LogicTeam
from tests.harness.route_team import RouteTeam, params_for
from tests.test_ssi_execution import instance


class Ticking:
    """A wall clock that moves `step` seconds at every reading: each measured span is one
    step per reading taken inside it, so the expected times are known without a real clock."""

    def __init__(self, step: float):
        self.t, self.step = 0.0, step

    def __call__(self) -> float:
        self.t += self.step
        return self.t


def test_each_award_takes_the_slowest_bid_plus_the_winner_determination():
    p = instance(2, n=3, m=5)
    # robot k's timer moves (k + 1) ms a reading: its bid takes (k + 1) ms; the auctioneer
    # (robot1, 1 ms a reading) also takes 1 ms to determine the winner
    logics = {r.id: Ssi(p, r.id, join_wait=0.0, timer=Ticking((k + 1) / 1000.0))
              for k, r in enumerate(p.robots)}
    team = LogicTeam(logics, MESSAGES)
    team.run(quiet=10)
    awards = logics["robot1"].awards
    assert len(awards) == len(p.tasks)
    # every round waits for every robot's answer (a bid, or "nothing" — timed alike), so each
    # award takes robot3's 3 ms, the slowest, plus the auctioneer's 1 ms to clear
    assert [round(a.ms, 6) for a in awards] == [4.0] * len(p.tasks)
    for other in ("robot2", "robot3"):  # the bidders learn each award's time from its Round
        assert [a.ms for a in logics[other].awards] == [a.ms for a in awards]


def records_of(team: RouteTeam) -> list:
    return [(f"{m.header.frame_id}/ssi/{kind}", encoding_for(m.TYPE_NAME), m.header.stamp,
             encode(m)) for kind, m in team.sent]


def test_a_runs_records_give_one_timed_decision_per_award_resends_counted_once():
    p = instance(4)
    team = RouteTeam(p, SSI.messages, lambda rid, body: SsiCoordinator(
        rid, params_for(p, SsiKeys(), 10.0), body))
    team.run_until_served()
    rounds = [m for kind, m in team.sent if kind == "round" and m.award >= 0]
    awarded = {(m.header.frame_id, m.round) for m in rounds}
    assert len(awarded) == len(p.tasks)  # one award per task, no loss, no takeover
    # a Round repeated: the same decision again, which must not count twice
    again = rounds[-1]
    h = again.header
    team.sent.append(("round", Round(Header(h.frame_id, h.stamp + 0.5, h.seq + 100),
                                     again.round, again.owners, again.award, again.cost,
                                     again.ms)))
    d = decisions(records_of(team), SSI, end=team.now + 1.0)
    assert d is not None and d.count == len(p.tasks)
    assert d.max_ms is not None and d.median_ms is not None and d.median_ms > 0
    assert d.max_ms == round(max(m.ms for m in rounds), 3)
    assert d.objective == "minsum"
