"""MURDOCH's subject addressing (docs/murdoch.md, Protocol): announcements go out on their
task's subject and reach only the robots with a skill for it; bids go to their auctioneer only;
each robot advertises its subjects (liveliness tokens), and a task's auctioneers are ranked
among the robots that serve it.
Real agents on the in-process bus and a manual clock (tests/harness/murdoch_team.py), with every sample
each agent's subscriptions deliver recorded at the agent (before any check of its own)."""

from mrta_agent.murdoch.architecture import MURDOCH
from mrta_agent.murdoch.params import takeover_bound
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.keys import first_chunk
from tests.harness.alliance_team import Spec, make_agent
from tests.harness.murdoch_team import Team

SKILLS = {"robot1": {"a": 0.2, "b": 0.3},   # rank 0: serves both, auctions both
          "robot2": {"a": 0.9},             # never hears b's announcements
          "robot3": {"b": 0.8},             # never hears a's announcements
          "robot4": {"a": 0.5, "b": 0.4}}


def spy(team: Team) -> dict[str, list[str]]:
    """Every key each agent's subscriptions deliver to it, its own messages included."""
    delivered: dict[str, list[str]] = {rid: [] for rid in team.agents}
    for rid, agent in team.agents.items():
        inner = agent._on_message

        def on_message(kind, sample, rid=rid, inner=inner):
            delivered[rid].append(sample.key)
            inner(kind, sample)
        agent._on_message = on_message  # the subscriptions call it by name
    return delivered


def test_the_subject_kinds_have_sub_keys_and_stay_coordination_keys():
    assert MURDOCH.every("announcement") == "*/murdoch/announcement/**"
    assert MURDOCH.every("bid") == "*/murdoch/bid/**"
    assert MURDOCH.every("claim") == "*/murdoch/claim"
    assert MURDOCH.is_coordination_key("robot1/murdoch/announcement/a")
    assert MURDOCH.is_coordination_key("robot2/murdoch/bid/robot1")


def test_announcements_reach_only_the_robots_that_serve_their_task(tmp_path):
    team = Team(tmp_path, SKILLS, ["a", "b"])
    delivered = spy(team)
    team.until(lambda: team.holders("a") and team.holders("b"))
    team.step(30)
    assert team.holders("a") == ["robot2"] and team.holders("b") == ["robot3"]
    sent = [s.key for s in team.messages("announcement")]
    assert {"robot1/murdoch/announcement/a", "robot1/murdoch/announcement/b"} <= set(sent)
    for rid, keys in delivered.items():
        heard = {k.split("/")[3] for k in keys if k.split("/")[2] == "announcement"}
        assert heard <= set(SKILLS[rid]), (rid, heard)
    assert not any("/announcement/b" in k for k in delivered["robot2"])
    assert not any("/announcement/a" in k for k in delivered["robot3"])
    # the agent's own count: teammates' announcements it received, of its subjects only
    for rid, agent in team.agents.items():
        expected = sum(1 for s in team.messages("announcement")
                       if not s.key.startswith(rid + "/") and s.key.split("/")[3] in SKILLS[rid])
        assert agent.received["announcement"] == expected


def test_bids_reach_their_auctioneer_only(tmp_path):
    team = Team(tmp_path, SKILLS, ["a", "b"])
    delivered = spy(team)
    team.until(lambda: team.holders("a") and team.holders("b"))
    bids = team.messages("bid")
    assert bids and {s.key.split("/")[3] for s in bids} == {"robot1"}  # robot1 auctions
    assert all(s.message.auctioneer == "robot1" for s in bids)
    for rid in ("robot2", "robot3", "robot4"):
        assert not [k for k in delivered[rid] if k.split("/")[2] == "bid"], rid
        assert team.agents[rid].received["bid"] == 0
    assert team.agents["robot1"].received["bid"] == len(bids)
    # awards and claims stay broadcast: every robot hears robot1's awards and others' claims
    team.step(2)
    for rid, agent in team.agents.items():
        assert agent.received["claim"] >= 1, rid
        assert rid == "robot1" or agent.received["award"] == len(team.messages("award")), rid


def announced(team: Team, task: str) -> list[tuple[str, float]]:
    """(auctioneer, seconds after the team's start) of every announcement of `task`, in order."""
    return [(first_chunk(s.key), round(s.message.header.stamp - 100.0, 6))
            for s in team.messages("announcement") if s.key.split("/")[3] == task]


SPLIT = {"robot1": {"a": 0.5}, "robot2": {"a": 0.9}, "robot3": {"b": 0.5}, "robot4": {"b": 0.9}}


def test_each_robot_advertises_its_subjects_right_before_its_agent_token(tmp_path):
    # before: one link carries a session's declarations in order, so a teammate holding the
    # agent token holds the subjects too (Agent.await_team waits for agent tokens only)
    team = Team(tmp_path, SPLIT, ["a", "b"])
    for rid, skills in SPLIT.items():
        mine = [k for k, alive in team.tokens if alive and k.startswith(rid + "/")]
        assert mine == [f"{rid}/murdoch/subject/{t}" for t in skills] + [f"{rid}/murdoch/agent"]
    team.step(1)
    servers = {"a": {"robot2"}, "b": {"robot3", "robot4"}}
    assert team.agents["robot1"].coordinator.core.servers == servers
    team.agents["robot1"].restart(team.clock.now())  # time restarts: a new logic, told again
    assert team.agents["robot1"].coordinator.core.servers == servers


def test_a_task_the_lowest_id_robot_cannot_serve_is_announced_at_once_by_the_first_that_can(
        tmp_path):
    # robot1 ranks first overall but serves only a: b's auctioneer is robot3, the lowest id
    # among b's servers, and announces it at the first tick, as robot1 announces a
    team = Team(tmp_path, SPLIT, ["a", "b"])
    team.step(1)
    assert announced(team, "a") == [("robot1", 0.0)] and announced(team, "b") == [("robot3", 0.0)]
    ranks = {rid: {t: agent.coordinator.core.rank(t) for t in SPLIT[rid]}
             for rid, agent in team.agents.items()}
    assert ranks == {"robot1": {"a": 0}, "robot2": {"a": 1}, "robot3": {"b": 0},
                     "robot4": {"b": 1}}
    took = team.until(lambda: team.holders("a") and team.holders("b"))
    assert team.holders("a") == ["robot2"] and team.holders("b") == ["robot4"]
    assert took <= 0.5 + 0.3 + 1e-9  # the bid window, then the award and the claim's ticks
    assert announced(team, "a") == [("robot1", 0.0)] and announced(team, "b") == [("robot3", 0.0)]


FIVE = {"robot1": {"a": 0.5}, "robot2": {"b": 0.1}, "robot3": {"a": 0.9}, "robot4": {"b": 0.9},
        "robot5": {"b": 0.5}}  # b's servers: robot2 (its auctioneer), robot4, robot5


def test_when_a_tasks_auctioneer_dies_the_next_robot_that_serves_it_steps_in_at_once(tmp_path):
    team = Team(tmp_path, FIVE, ["a", "b"])
    team.until(lambda: team.holders("a") == ["robot3"] and team.holders("b") == ["robot4"])
    assert announced(team, "b") == [("robot2", 0.0)]
    assert team.agents["robot5"].coordinator.core.rank("b") == 2
    team.step(3)
    team.kill("robot2")  # b's auctioneer and its holder together
    team.kill("robot4")
    took = team.until(lambda: team.holders("b") == ["robot5"])
    # robot5 is first among b's live servers, though robot1 and robot3 have lower ids
    assert team.agents["robot5"].coordinator.core.rank("b") == 0
    assert team.messages("award")[-1].key == "robot5/murdoch/award"
    assert took <= takeover_bound(team.agents["robot5"].coordinator.params.robot) + 1e-9
    assert team.holders("a") == ["robot3"]


def test_a_frozen_auctioneer_is_replaced_one_period_per_rank_among_the_tasks_servers(tmp_path):
    team = Team(tmp_path, FIVE, ["a", "b"])
    team.step(1)
    assert announced(team, "b") == [("robot2", 0.0)]
    team.frozen.add("robot2")  # token alive, silent: bids reach nobody who awards
    team.until(lambda: team.holders("b"))
    # robot4, rank 1 among b's servers (rank 3 among all robots), waits (rank + 1) periods
    assert announced(team, "b")[1] == ("robot4", 2 * 2.0)
    assert team.holders("b") == ["robot4"]


def test_subject_tokens_count_only_from_teammates(tmp_path):
    team = Team(tmp_path, {"robot2": {"b": 0.5}, "robot3": {"b": 0.9}}, ["b"],
                roster=["robot1", "robot2", "robot3"])
    forger = InProcBus(team.net)
    forger.declare_token("robot1/murdoch/subject/b")  # no agent token (yet): not a teammate
    forger.declare_token("robot0/murdoch/agent")  # off the roster, agent token and all
    forger.declare_token("robot0/murdoch/subject/b")
    team.step(1)
    core = team.agents["robot2"].coordinator.core
    assert core.servers["b"] == {"robot3"} and core.rank("b") == 0
    assert announced(team, "b") == [("robot2", 0.0)]
    assert all(agent.ignored_outsiders == 2 for agent in team.agents.values())
    agent_token = forger.declare_token("robot1/murdoch/agent")  # now robot1's subject counts
    team.step(1)
    assert core.servers["b"] == {"robot1", "robot3"} and core.rank("b") == 1
    agent_token.close()  # and goes with its agent token, though its subject token lives
    team.step(1)
    assert core.servers["b"] == {"robot3"} and core.rank("b") == 0
    forger.close()


class _RecordingBus:
    """Records what an agent declares, watches and subscribes to; delivers nothing."""

    class _Handle:
        def close(self) -> None:
            pass

    def __init__(self):
        self.tokens, self.watches = [], []

    def subscribe(self, key_expr, handler, msg_type=None, **kwargs):
        return self._Handle()

    def watch_liveliness(self, key_expr, handler):
        self.watches.append(key_expr)
        return self._Handle()

    def declare_token(self, key):
        self.tokens.append(key)
        return self._Handle()

    def publish(self, key, message, lossy=False):
        pass


def test_alliance_advertises_no_subject_and_watches_none():
    bus = _RecordingBus()
    agent = make_agent("robot1", Spec(spin=10, broadcast=1, tau=3, theta=20, fast=2, expected=60,
                                      yielding=5), bus, ManualClock(0.0))
    assert bus.tokens == ["robot1/alliance/agent"] and bus.watches == ["*/alliance/agent"]
    assert agent.advertised() == ()


def test_a_crashed_holder_is_replaced_through_the_subjects(tmp_path):
    team = Team(tmp_path, SKILLS, ["a", "b"])
    delivered = spy(team)
    team.until(lambda: team.holders("a") == ["robot2"] and team.holders("b") == ["robot3"])
    team.step(5)
    team.kill("robot2")
    took = team.until(lambda: team.holders("a") == ["robot4"])
    assert took <= takeover_bound(team.agents["robot4"].coordinator.params.robot) + 1e-9
    assert team.holders("b") == ["robot3"]
    assert not any("/announcement/a" in k for k in delivered["robot3"])
    assert not [k for k in delivered["robot4"] if k.split("/")[2] == "bid"]
