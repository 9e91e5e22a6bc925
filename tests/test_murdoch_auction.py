"""MURDOCH's auctions and leases in virtual time: real agents on the in-process bus and a manual
clock (tests/harness/murdoch_team.py), the pure auction logic, and the parameter files' errors."""

import tempfile
from pathlib import Path

import pytest

from mrta_agent.murdoch.auction import Murdoch
from mrta_agent.murdoch.messages import Claim
from mrta_agent.murdoch.params import load_params, load_robot, takeover_bound
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from tests.harness.alliance_fixtures import write
from tests.harness.murdoch_team import Team, robot_doc, tasks_doc

TICK = 0.1


def test_the_highest_utility_wins_and_the_winner_renews_its_lease(tmp_path):
    team = Team(tmp_path, {"robot1": {"a": 0.3}, "robot2": {"a": 0.9}, "robot3": {"a": 0.5}}, ["a"])
    team.until(lambda: team.holders("a"))
    assert team.holders("a") == ["robot2"]
    awards = team.messages("award")
    assert [(s.key, s.message.winner, s.message.utility) for s in awards] == \
        [("robot1/murdoch/award", "robot2", 0.9)]  # robot1, the lowest id, auctions
    bids = {s.message.header.frame_id: s.message.utility for s in team.messages("bid")}
    assert bids == {"robot2": 0.9, "robot3": 0.5}  # the auctioneer's own bid never goes out
    team.step(20)
    claims = [s for s in team.messages("claim") if s.message.task_id == "a"]
    assert {s.message.header.frame_id for s in claims} == {"robot2"}
    assert 4 <= len(claims) <= 6  # at once, then every 0.5 s over 2 s


def test_distance_to_the_task_lowers_the_bid(tmp_path):
    team = Team(tmp_path, {"robot1": {"a": 1.0}, "robot2": {"a": 1.0}}, ["a"],
                locations={"a": (10.0, 0.0)})
    team.pose = {"robot1": (0.0, 0.0), "robot2": (8.0, 0.0)}
    team.until(lambda: team.holders("a"))
    assert team.holders("a") == ["robot2"]  # 1 − 0.1·2 beats 1 − 0.1·10


def test_ties_go_to_the_lower_robot_id_whoever_auctions(tmp_path):
    team = Team(tmp_path, {"robot3": {"a": 0.7}, "robot2": {"a": 0.7}, "robot1": {"a": 0.2}},
                ["a"])
    team.until(lambda: team.holders("a"))
    assert team.holders("a") == ["robot2"]
    (tmp_path / "x").mkdir()
    team2 = Team(tmp_path / "x", {"robot2": {"a": 0.7}, "robot3": {"a": 0.7}}, ["a"])
    team2.until(lambda: team2.holders("a"))
    assert team2.holders("a") == ["robot2"]  # robot2 auctions and wins against its tie


def test_greedy_single_round_assignment_gives_each_robot_one_task(tmp_path):
    # robot1 is best at both; greedy: robot1 takes a (0.9), robot2 gets b (0.6 > robot1's 0.8
    # which is taken) — never two tasks to one robot
    team = Team(tmp_path, {"robot1": {"a": 0.9, "b": 0.8}, "robot2": {"a": 0.5, "b": 0.6}},
                ["a", "b"])
    team.until(lambda: team.holders("a") and team.holders("b"))
    assert team.holders("a") == ["robot1"] and team.holders("b") == ["robot2"]


def test_no_bids_no_award_and_the_task_is_announced_again(tmp_path):
    team = Team(tmp_path, {"robot1": {"a": 1.0}, "robot2": {"a": 1.0}}, ["a"])
    team.blind = {"robot1", "robot2"}  # no sonar: the required resource is missing
    team.step(55)  # 5.5 s
    assert not team.messages("award") and not team.holders("a")
    announcements = team.messages("announcement")
    assert [s.key for s in announcements] == ["robot1/murdoch/announcement/a"] * 3  # t=0, 2, 4
    team.blind = set()
    team.until(lambda: team.holders("a"), limit=3.0)


def test_a_lease_that_stops_is_auctioned_again_within_its_bound(tmp_path):
    team = Team(tmp_path, {"robot1": {"a": 0.2}, "robot2": {"a": 0.9}, "robot3": {"a": 0.5}}, ["a"])
    team.until(lambda: team.holders("a"))
    team.step(10)
    assert team.holders("a") == ["robot2"]
    team.frozen.add("robot2")  # stops renewing, its token still alive: only the lease tells
    taken = team.until(lambda: team.holders("a") == ["robot3"])
    bound = takeover_bound(team.agents["robot3"].coordinator.params.robot)  # lease + window + 3 ticks
    assert bound == pytest.approx(2.0 + 0.5 + 0.3)
    # from robot2's last renewal (up to one renewal period before it froze) to robot3's claim
    assert taken <= bound + 1e-9
    assert taken >= 2.0 - 0.5  # not before the lease could have lapsed


def test_the_loss_of_the_auctioneer_still_leads_to_an_allocation(tmp_path):
    # robot1 auctions (lowest id) and freezes right after announcing: bids reach nobody who
    # awards; robot2, next in rank, steps in one reannounce period later
    team = Team(tmp_path, {"robot1": {"a": 0.1}, "robot2": {"a": 0.5}, "robot3": {"a": 0.9}}, ["a"])
    team.step(1)
    assert [s.key for s in team.messages("announcement")] == ["robot1/murdoch/announcement/a"]
    team.frozen.add("robot1")
    took = team.until(lambda: team.holders("a"))
    assert team.holders("a") == ["robot3"]
    assert team.messages("award")[0].key == "robot2/murdoch/award"
    # robot2 (rank 1) stays silent for (rank + 1) reannounce periods after the last
    # announcement — a live rank 0 re-announces before then — and then auctions
    announced = [s.message.header.stamp for s in team.messages("announcement")
                 if s.key.startswith("robot2/")]
    assert announced and announced[0] - 100.0 == pytest.approx(2 * 2.0)
    assert took <= 2 * 2.0 + 0.5 + 0.3 + 1e-9


def test_a_dead_auctioneer_is_replaced_at_once(tmp_path):
    # robot1 auctions, robot2 holds a, robot3 holds b, robot4 is idle; robot1 and robot2 die
    # together: their tokens go, robot3 ranks first and auctions a within the usual bound
    team = Team(tmp_path, {"robot1": {"a": 0.1, "b": 0.1}, "robot2": {"a": 0.9, "b": 0.3},
                           "robot3": {"a": 0.5, "b": 0.8}, "robot4": {"a": 0.4, "b": 0.2}},
                ["a", "b"])
    team.until(lambda: team.holders("a") == ["robot2"] and team.holders("b") == ["robot3"])
    team.step(3)
    team.kill("robot1")
    team.kill("robot2")
    took = team.until(lambda: team.holders("a") == ["robot4"])
    assert team.agents["robot3"].coordinator.core.rank("a") == 0
    assert team.messages("award")[-1].key == "robot3/murdoch/award"
    assert took <= takeover_bound(team.agents["robot3"].coordinator.params.robot) + 1e-9
    assert team.holders("b") == ["robot3"]


def test_a_winner_that_cannot_progress_gives_the_task_back(tmp_path):
    team = Team(tmp_path, {"robot1": {"a": 0.9}, "robot2": {"a": 0.4}}, ["a"])
    team.until(lambda: team.holders("a"))
    assert team.holders("a") == ["robot1"]
    team.blind = {"robot1"}  # its sonar dies: not progressing
    took = team.until(lambda: team.holders("a") == ["robot2"])
    releases = team.messages("release")
    assert releases and releases[0].message.header.frame_id == "robot1"
    assert "no progress" in releases[0].message.reason
    # sensor timeout 1 s + give_up_delay 3 s, then an auction (window 0.5 s, ticks)
    assert 1.0 + 3.0 <= took <= 1.0 + 3.0 + 0.5 + 0.5


def test_of_two_holders_the_later_claim_yields():
    team_params = load_robot_from_doc({"a": 1.0})
    core = Murdoch("robot2", team_params.robot, team_params.tasks)
    core.task, core.since, core.last_claim = "a", 10.0, 10.0

    class Fresh:
        def fresh(self, topic, now): return True
        def applicable(self, task, now): return True
        def done(self, task, now): return False
        def pose(self): return None

    core.hear("claim", "robot3", Claim(Header("robot3", 11.0, 1), "a", 11.0, 2.0), 11.0)
    out, changes = core.tick(11.0, Fresh())
    assert core.task == "a" and not changes  # robot3 claimed later: robot3 yields, not us
    core.hear("claim", "robot1", Claim(Header("robot1", 11.1, 1), "a", 9.5, 2.0), 11.1)
    out, changes = core.tick(11.2, Fresh())
    assert core.task == "a" and not changes  # heard once: not yet a contract (issue 51)
    core.hear("claim", "robot1", Claim(Header("robot1", 11.6, 2), "a", 9.5, 2.0), 11.6)
    out, changes = core.tick(11.7, Fresh())  # renewed: robot1 claimed earlier, we yield
    assert core.task is None and changes[0].kind == "released"
    assert "robot1" in changes[0].reason and [o.kind for o in out] == ["release"]



def test_hear_takes_murdochs_kinds_only_each_of_its_own_type():
    """One entry for what is heard: a kind that is not MURDOCH's, or a message of another kind's
    type, is refused (False) and changes nothing; a claim of the right type takes effect."""
    params = load_robot_from_doc({"a": 1.0})
    core = Murdoch("robot2", params.robot, params.tasks)
    claim = Claim(Header("robot3", 1.0, 1), "a", 1.0, 2.0)
    assert core.hear("progress", "robot3", claim, 1.0) is False
    assert core.hear("award", "robot3", claim, 1.0) is False
    assert core.leases["a"] == {} and core.held_until == {}
    assert core.hear("claim", "robot3", claim, 1.0) is True
    assert set(core.leases["a"]) == {"robot3"} and core.held_until["a"] == 3.0

def load_robot_from_doc(skills):
    d = Path(tempfile.mkdtemp())
    return load_params(write(d / "r.yaml", robot_doc(skills)),
                       write(d / "t.yaml", tasks_doc(list(skills))))


@pytest.mark.parametrize("change, message, key", [
    ({"lease_timeout": 0.5}, "must be longer than renewal_period", "lease_timeout"),
    ({"bid_window": 0.01}, "shorter than the tick period", "bid_window"),
    ({"reannounce_period": 0.4}, "must be longer than bid_window", "reannounce_period"),
    ({"lease_timout": 2.0}, "did you mean 'lease_timeout'", "lease_timout"),
    ({"pose_topic": "gps"}, "not among the robot's sensors", "pose_topic"),
])
def test_bad_robot_files_name_file_line_and_key(tmp_path, change, message, key):
    doc = robot_doc({"a": 1.0})
    doc.update(change)
    f = write(tmp_path / "robot1_murdoch_params.yaml", doc)
    with pytest.raises(ConfigError) as err:
        load_robot(f)
    text = str(err.value)
    assert message in text and f"'{key}'" in text and str(f) in text
    assert err.value.line is not None


def test_a_skill_for_a_task_the_tasks_file_lacks_is_refused(tmp_path):
    rf = write(tmp_path / "r.yaml", robot_doc({"wandr": 1.0}))
    tf = write(tmp_path / "t.yaml", tasks_doc(["wander"]))
    with pytest.raises(ConfigError, match="did you mean 'wander'"):
        load_params(rf, tf)


def test_the_shipped_patrol_parameters_load_and_bound_the_takeover():
    from mrta_zenoh.architectures import architecture
    from tests.harness.helpers import CONFIGS
    bound_of = architecture("murdoch").takeover_bound
    cfg = CONFIGS / "applications" / "patrol_murdoch" / "config"
    for rid in ("robot1", "robot2", "robot3"):
        p = load_params(cfg / f"{rid}_murdoch_params.yaml", cfg / "tasks_murdoch_params.yaml",
                        cfg / "layers_murdoch_params.yaml")
        assert not p.warnings
        assert sorted(p.tasks) == ["border_protection", "report", "wander"]
    assert bound_of(cfg / "robot1_murdoch_params.yaml", "wander") == pytest.approx(2.8)
