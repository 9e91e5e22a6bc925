"""MURDOCH believes a message only for what its sender can claim (issue 51, docs/security.md):
each test forges what a hostile probe sent — once, as a forger on an open bus can (or a
certified robot under its own key) — and fails on the code before these rules. Real agents on
the in-process bus and a manual clock where the effect is the team's (tests/harness/murdoch_team.py),
the pure auction logic where it is one robot's belief."""

from __future__ import annotations

from mrta_agent.murdoch.architecture import MURDOCH
from mrta_agent.murdoch.auction import Murdoch
from mrta_agent.murdoch.messages import Announcement, Award, Claim, Revoke
from mrta_agent.murdoch.params import load_params
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.messages import Header
from tests.harness.alliance_fixtures import write
from tests.harness.murdoch_team import Team, robot_doc, tasks_doc
from tests.test_murdoch_progress import _Able, serving


def core_of(tmp_path, robot: str, skills: dict[str, float], tasks=("a", "b")) -> Murdoch:
    params = load_params(write(tmp_path / f"{robot}.yaml", robot_doc(skills)),
                         write(tmp_path / "t.yaml", tasks_doc(list(tasks), progress_timeout=5.0)))
    return Murdoch(robot, params.robot, params.tasks)


def test_one_forged_claim_with_an_earlier_start_displaces_no_holder(tmp_path):
    # robot1 wins a at 100.5 (it auctions, bids 1.0). At 103.0 a forger says, once, in robot3's
    # name (alive, idle), "I hold a since 100.0". Before: robot1 yielded to the earlier claim
    # at its next tick and a waited for the forged lease. Now a claim heard once is no
    # contract: robot1 keeps a; the forged lease lapses and robot1 counts it unrenewed.
    team = Team(tmp_path, {"robot1": {"a": 1.0}, "robot2": {"a": 0.5}, "robot3": {"a": 0.4}},
                ["a"])
    team.until(lambda: team.holders("a") == ["robot1"])
    team.step(25)
    forger = InProcBus(team.net)
    forger.publish(MURDOCH.key("robot3", "claim"),
                   Claim(Header("robot3", team.clock.now(), 999), "a", 100.0, 20.0))
    for _ in range(60):  # 6 s: three leases
        team.step()
        assert team.holders("a") == ["robot1"]
    assert not [s for s in team.messages("release") if s.key.startswith("robot1/")]
    assert len(team.messages("award")) == 1
    refused = team.agents["robot1"].coordinator.refusals()
    assert refused == {("claim", "robot3", "claim_not_renewed", False): 1}


def test_a_renewed_earlier_claim_still_wins_two_holders_after_a_partition(tmp_path):
    """The rule above keeps the protocol's own case: a holder cut off from the other renews its
    claim, and once it is heard renewed the later holder yields."""
    core = core_of(tmp_path, "robot2", {"a": 1.0})
    core.task, core.since, core.last_claim = "a", 10.0, 10.0
    core.hear("claim", "robot1", Claim(Header("robot1", 20.0, 40), "a", 8.0, 2.0), 20.0)
    assert core.tick(20.1, _Able())[1] == []
    core.hear("claim", "robot1", Claim(Header("robot1", 20.5, 41), "a", 8.0, 2.0), 20.5)
    assert [c.kind for c in core.tick(20.6, _Able())[1]] == ["released"]
    assert not core.refused


def test_a_claim_from_a_robot_heard_renewing_another_task_since_is_refused_as_forged(tmp_path):
    # robot2 holds b and renews it (heard at 10 and 14); a claim in its name "a since 11" is
    # one no robot makes — it would have held two tasks from 11 to 14
    core = core_of(tmp_path, "robot3", {"a": 1.0, "b": 1.0})
    for t in (10.0, 14.0):
        core.hear("claim", "robot2", Claim(Header("robot2", t, 1), "b", 10.0, 2.0), t)
    core.hear("claim", "robot2", Claim(Header("robot2", 14.1, 99), "a", 11.0, 2.0), 14.1)
    assert "robot2" not in core.leases["a"] and "a" not in core.held_until
    assert core.refused == {("claim", "robot2", "claim_contradicted", True): 1}
    # its own next contract, after b's last renewal, is believed
    core.hear("claim", "robot2", Claim(Header("robot2", 15.0, 2), "a", 15.0, 2.0), 15.0)
    assert core.leases["a"]["robot2"].since == 15.0


def test_a_revocation_of_a_contract_never_heard_of_bars_nobody(tmp_path):
    """Before, any Revoke naming a holder and a `since` this robot never heard barred that
    holder from the task for a progress_timeout, at every robot; and a robot that serves no
    such task (a certified robot under its own key) could revoke."""
    core = core_of(tmp_path, "robot3", {"a": 1.0})
    serving(core, "robot2")
    core.hear("claim", "robot1", Claim(Header("robot1", 10.0, 1), "a", 10.0, 2.0), 10.0)
    core.hear("revoke", "robot2", Revoke(Header("robot2", 11.0, 9), "a", "robot1", 3.0, "x"), 11.0)
    core.hear("revoke", "robot4", Revoke(Header("robot4", 16.0, 9), "a", "robot1", 10.0, "x"), 16.0)
    assert not core.barred("a", "robot1", 16.0) and "robot1" in core.leases["a"]
    assert core.refused == {("revoke", "robot2", "revoke_unknown", False): 1,
                            ("revoke", "robot4", "not_monitor", False): 1}
    # the task's monitor, on time, for the contract heard: believed
    core.hear("revoke", "robot2", Revoke(Header("robot2", 16.0, 2), "a", "robot1", 10.0, "x"), 16.0)
    assert core.barred("a", "robot1", 16.0) and "robot1" not in core.leases["a"]
    # another monitor saying the same afterwards is no refusal
    serving(core, "robot4")
    core.hear("revoke", "robot4", Revoke(Header("robot4", 16.1, 2), "a", "robot1", 10.0, "x"), 16.1)
    assert sum(core.refused.values()) == 2


def test_an_award_for_an_auction_never_announced_holds_nothing_at_the_tasks_servers(tmp_path):
    # before: robot3, which serves a, counted a held (and robot2 busy) for a lease
    core = core_of(tmp_path, "robot3", {"a": 1.0})
    core.hear("award", "robot1", Award(Header("robot1", 10.0, 9), 7, "a", "robot2", 1.0), 10.0)
    assert "a" not in core.held_until and "robot2" not in core.awarded
    assert core.refused == {("award", "robot1", "award_not_announced", False): 1}
    core.hear("announcement", "robot1", Announcement(Header("robot1", 10.5, 2), 8, "a", (), 0.5),
              10.5)
    core.hear("award", "robot1", Award(Header("robot1", 11.0, 3), 8, "a", "robot2", 1.0), 11.0)
    assert core.held_until["a"] == 13.0 and core.awarded["robot2"] == ("a", 13.0)


def test_a_robot_awarded_what_it_never_bid_for_says_so_and_its_teammates_stop_waiting(tmp_path):
    """A forged Award naming robot2 for b, heard by robot3 (which does not serve b, so hears
    no announcement of it, and believed robot2 busy for a lease): robot2 refuses it and
    releases b at once; robot3, hearing the release, counts robot2 free and b unheld again."""
    winner = core_of(tmp_path, "robot2", {"a": 1.0, "b": 1.0})
    other = core_of(tmp_path, "robot3", {"a": 1.0})
    forged = Award(Header("robot1", 10.0, 9), 7, "b", "robot2", 1.0)
    for core in (winner, other):
        core.hear("award", "robot1", forged, 10.0)
    assert other.awarded == {"robot2": ("b", 12.0)}  # it cannot tell
    out, changes = winner.tick(10.1, _Able())
    assert not changes and ("release", "b") in [(o.kind, o.fields["task_id"]) for o in out]
    (release,) = [o for o in out if o.kind == "release"]
    other.hear("release", "robot2", release.message(MURDOCH.messages, Header("robot2", 10.1, 1)),
               10.1)
    assert other.awarded == {} and other.held_until["b"] == 10.1
    assert winner.refused == {("award", "robot1", "award_not_bid", True): 1}
