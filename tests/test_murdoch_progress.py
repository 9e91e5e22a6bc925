"""MURDOCH's progress monitoring: a robot that keeps renewing its lease but does not finish its
task within the task's progress_timeout loses it — its auctioneer (ranked among the task's
other servers) revokes the contract, the task is auctioned again, and the holder gives it back
and may not win it again for a progress_timeout. Real agents on the in-process bus and a manual
clock (tests/harness/murdoch_team.py), the ticks computed by hand in the comments."""

from __future__ import annotations

import pytest

from mrta_agent.murdoch.auction import Murdoch
from mrta_agent.murdoch.messages import Claim, Revoke
from mrta_agent.murdoch.params import PROGRESS_TIMEOUT, load_params
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from tests.harness.alliance_fixtures import write
from tests.harness.murdoch_team import Team, robot_doc, tasks_doc


def sent(team: Team, kind: str, after: float = 0.0) -> list[tuple[float, str]]:
    return [(round(s.message.header.stamp, 2), s.key.split("/")[0])
            for s in team.messages(kind) if s.message.header.stamp >= after]


def test_a_holder_that_keeps_renewing_without_finishing_loses_its_task(tmp_path):
    # progress_timeout 5 s. t=100.0: robot1 (rank 0) announces a, bids 1.0 itself; robot2
    # bids 0.5. 100.5: robot1 wins its own auction and claims (since 100.5); robot2 hears the
    # claim at 100.5. robot1 renews for ever, never finishing: robot2, the task's only other
    # server, revokes at 100.5 + 5 = 105.5. robot1 hears it at 105.6, gives a back and may
    # not bid for it until 110.6; 105.7: a is unheld, robot1 (rank 0) announces it; robot2
    # bids; 106.2 the window closes: robot2 wins and claims.
    team = Team(tmp_path, {"robot1": {"a": 1.0}, "robot2": {"a": 0.5}}, ["a"],
                progress_timeout=5.0)
    team.until(lambda: team.holders("a") == ["robot1"])
    took = team.until(lambda: team.holders("a") == ["robot2"])
    assert team.clock.now() == pytest.approx(106.3)  # the step after robot2's tick at 106.2
    assert sent(team, "revoke") == [(105.5, "robot2")]
    (revoke,) = team.messages("revoke")
    assert (revoke.message.holder, revoke.message.since) == ("robot1", pytest.approx(100.5))
    assert [(t, r) for t, r in sent(team, "release")] == [(105.6, "robot1")]
    assert sent(team, "announcement", after=101.0) == [(105.7, "robot1")]
    assert [s.message.winner for s in team.messages("award")] == ["robot1", "robot2"]
    assert took == pytest.approx(5.7)
    reason = team.agents["robot1"].coordinator.history[-1][1].reason
    assert reason.startswith("revoked by robot2")
    # the contract robot2 now holds is watched too: at 106.2 + 5 it is revoked in turn, and
    # robot1, barred from a until 110.6, may have it back
    team.until(lambda: team.holders("a") == ["robot1"], limit=10.0)
    assert sent(team, "revoke", after=106.0) == [(111.2, "robot1")]
    assert sent(team, "bid", after=111.0) == []  # robot2, revoked, does not bid for it again


def test_a_frozen_monitor_is_stood_in_for_one_reannounce_period_per_rank(tmp_path):
    # robot2 (the first of a's other servers) is frozen — alive, silent — so robot3, of rank
    # 1 among them, revokes one reannounce_period (2 s) later: 100.5 + 5 + 2 = 107.5
    team = Team(tmp_path, {"robot1": {"a": 1.0}, "robot2": {"a": 0.5}, "robot3": {"a": 0.4}},
                ["a"], progress_timeout=5.0)
    team.until(lambda: team.holders("a") == ["robot1"])
    team.frozen.add("robot2")
    team.until(lambda: team.holders("a") == ["robot3"])
    assert sent(team, "revoke") == [(107.5, "robot3")]


def test_no_revocation_while_the_task_is_done_within_its_timeout(tmp_path):
    # the default timeout (60 s) is longer than these 30 s: robot1 keeps a, nobody revokes
    team = Team(tmp_path, {"robot1": {"a": 1.0}, "robot2": {"a": 0.5}}, ["a"])
    assert team.agents["robot2"].coordinator.core.tasks["a"].progress_timeout == \
        PROGRESS_TIMEOUT == 60.0
    team.step(300)
    assert team.holders("a") == ["robot1"] and not team.messages("revoke")


def serving(core: Murdoch, *robots: str, task: str = "a") -> None:
    """`robots` are live teammates that advertise `task` (monitors of its contracts)."""
    for r in robots:
        core.teammate(r, True)
        core.teammate_subject(r, task, True)


class _Able:
    def fresh(self, topic, now): return True
    def applicable(self, task, now): return True
    def done(self, task, now): return False
    def pose(self): return None


def test_a_revoked_contracts_claims_are_ignored_and_its_holder_barred(tmp_path):
    """A holder too stuck to hear the revocation goes on claiming the old contract: nobody
    counts it, and an auctioneer does not award the task back to it while it is barred."""
    params = load_params(write(tmp_path / "r.yaml", robot_doc({"a": 1.0})),
                         write(tmp_path / "t.yaml", tasks_doc(["a"], progress_timeout=5.0)))
    core = Murdoch("robot3", params.robot, params.tasks)
    for r in ("robot1", "robot2"):
        core.teammate(r, True)
        core.teammate_subject(r, "a", True)
    core.hear("claim", "robot1", Claim(Header("robot1", 10.0, 1), "a", 10.0, 2.0), 10.0)
    core.hear("revoke", "robot2", Revoke(Header("robot2", 15.0, 1), "a", "robot1", 10.0, "x"), 15.0)
    core.hear("claim", "robot1", Claim(Header("robot1", 15.5, 2), "a", 10.0, 2.0), 15.5)
    assert "robot1" not in core.leases["a"] and core.held_until["a"] == 15.0
    assert core.barred("a", "robot1", 19.9) and not core.barred("a", "robot1", 20.1)
    # a new contract of the same robot (a later since) counts again
    core.hear("claim", "robot1", Claim(Header("robot1", 30.0, 3), "a", 29.5, 2.0), 30.0)
    assert core.leases["a"]["robot1"].since == 29.5


def test_a_bad_progress_timeout_names_file_line_and_key(tmp_path):
    doc = tasks_doc(["a"], progress_timeout=-1.0)
    f = write(tmp_path / "t.yaml", doc)
    with pytest.raises(ConfigError) as err:
        load_params(write(tmp_path / "r.yaml", robot_doc({"a": 1.0})), f)
    assert "progress_timeout" in str(err.value) and str(f) in str(err.value)
    assert err.value.line is not None


class _Served:
    """A holder whose layers finished its task: done, and (as a delivered task's evaluator
    says) no longer applicable."""

    def fresh(self, topic, now): return True
    def applicable(self, task, now): return False
    def done(self, task, now): return True
    def pose(self): return None


def test_a_holder_gives_a_served_task_back_at_once_not_give_up_delay_later(tmp_path):
    """The interval a MURDOCH robot's claims and release draw ends where its service did
    (issue 51: it ended ≈ give_up_delay, 3 s, after `done_at`, the served task's evaluator
    having turned inapplicable, which looked like a stall); and the task is not barred from
    it as a stalled one would be."""
    params = load_params(write(tmp_path / "r.yaml", robot_doc({"a": 1.0})),
                         write(tmp_path / "t.yaml", tasks_doc(["a"])))
    core = Murdoch("robot1", params.robot, params.tasks)
    core.task, core.since, core.last_claim = "a", 10.0, 10.0
    out, changes = core.tick(12.0, _Served())
    assert core.task is None and [(c.kind, c.reason) for c in changes] == [("released", "done")]
    assert [(o.kind, o.fields["reason"]) for o in out] == [("release", "done")]
    assert "a" not in core.cooldown


def test_a_revocation_before_the_contract_ran_its_progress_timeout_is_refused_and_counted(
        tmp_path):
    """A Revoke is believed only for what a monitor can say: a contract that has run its
    progress_timeout (less a lease for delivery delays). One sent sooner — a forger's, or a
    certified robot's under its own key — neither ends a teammate's contract nor makes the
    holder give its task back; it is counted (`revoke_early`, forged) for the summary."""
    params = load_params(write(tmp_path / "r.yaml", robot_doc({"a": 1.0})),
                         write(tmp_path / "t.yaml", tasks_doc(["a"], progress_timeout=5.0)))
    watcher = Murdoch("robot3", params.robot, params.tasks)
    holder = Murdoch("robot1", params.robot, params.tasks)
    holder.task, holder.since, holder.last_claim = "a", 10.0, 10.0
    for core in (watcher, holder):
        serving(core, "robot2")
    watcher.hear("claim", "robot1", Claim(Header("robot1", 10.0, 1), "a", 10.0, 2.0), 10.0)
    early = Revoke(Header("robot2", 11.0, 1), "a", "robot1", 10.0, "forged")
    for core in (watcher, holder):
        core.hear("revoke", "robot2", early, 11.0)
        assert core.refused == {("revoke", "robot2", "revoke_early", True): 1}
    assert "robot1" in watcher.leases["a"] and not watcher.barred("a", "robot1", 11.0)
    _, changes = holder.tick(11.1, _Able())
    assert holder.task == "a" and not changes
    # on time (10.0 + 5 − the 2 s lease slack): believed, as tests above show end to end
    watcher.hear("revoke", "robot2", Revoke(Header("robot2", 13.0, 2), "a", "robot1", 10.0, "late"),
                 13.0)
    assert "robot1" not in watcher.leases["a"] and watcher.barred("a", "robot1", 13.0)
    assert sum(watcher.refused.values()) == 1


def test_an_award_for_an_auction_the_robot_did_not_bid_in_is_refused_and_counted(tmp_path):
    """An Award is believed only for a bid: one naming this robot in an auction it did not bid
    in (a forger's, or a certified robot's under its own key) does not make it take the task,
    and is counted (`award_not_bid`, forged); the award for its real bid is taken."""
    from mrta_agent.murdoch.messages import Announcement, Award
    params = load_params(write(tmp_path / "r.yaml", robot_doc({"a": 1.0, "b": 1.0})),
                         write(tmp_path / "t.yaml", tasks_doc(["a", "b"])))
    core = Murdoch("robot2", params.robot, params.tasks)
    core.hear("award", "robot1", Award(Header("robot1", 10.0, 1), 7, "a", "robot2", 1.0), 10.0)
    out, changes = core.tick(10.1, _Able())
    assert core.task is None and not changes
    assert core.refused == {("award", "robot1", "award_not_bid", True): 1}
    core.hear("announcement", "robot1", Announcement(Header("robot1", 10.1, 2), 8, "b", (), 0.5),
              10.1)
    out, _ = core.tick(10.2, _Able())
    assert [o.kind for o in out] == ["bid"]
    core.hear("award", "robot1", Award(Header("robot1", 10.6, 3), 8, "b", "robot2", 1.0), 10.6)
    _, changes = core.tick(10.7, _Able())
    assert core.task == "b" and [c.kind for c in changes] == ["won"]
    assert sum(core.refused.values()) == 1
