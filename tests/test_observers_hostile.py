"""Observers survive any input, and the team is known: the pure state
on a manual clock and the in-process bus. The same attacks against real processes are in
tests/process/test_observers_attack.py."""

import io
import logging
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rich.console import Console

from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header, Odometry, PointCloud, Pose2D, Twist
from mrta_zenoh.ros2 import names
from mrta_zenoh.ros2.graph import Ros2Graph
from mrta_zenoh.ros2.names import COMMANDS, Ros2NameError
from mrta_zenoh.untrusted import visible
from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_agent.runtime.host import AgentOptions
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.state import Supervisor
from mrta_supervisor.live.view import render
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write

BAD_TOKEN = "@ros2_lv/0/abcd/2/2/NN/%/%a-b/node"  # namespace /a-b is no ROS name
HASH = "RIHS01_" + "0" * 64
IRC = "alliance_msgs/InterRobotCommunication"
ESC = "\x1b]0;pwned\x07\x1b[2J"  # set the title, clear the screen


@pytest.fixture
def sup():
    app, arch = resolve_application("patrol")
    return Supervisor(arch, app, 0.0, unknown_expiry=10.0)


def alarms(sup, now):
    return {(a["kind"], a["subject"]) for a in sup.snapshot(now)["alarms"]}


def states(sup, now):
    return {r["id"]: r["state"] for r in sup.snapshot(now)["robots"]}


def shown(snap) -> str:
    buf = io.StringIO()
    Console(file=buf, width=120, color_system=None).print(render(snap, 120))
    return buf.getvalue()


# ------------------------------------------------------------------ the ROS 2 graph

@pytest.mark.parametrize("key", [
    BAD_TOKEN,
    "@ros2_lv/0/z/1/1/NN/%/%robot1/no-dash",                   # node name
    "@ros2_lv/0/z/1/1/NN/%/%robot1/" + "n" * 3000,             # absurdly long
    names.endpoint_token(0, "z", 1, 2, "MP", "/robot1", "n", "/ok", "std_msgs/msg/String",
                         HASH, COMMANDS).replace("%ok", "%a-b"),  # topic
    "@ros2_lv/0/z/1/1/NN/%/%ro\x1bbot/n",                      # control characters
])
def test_a_token_whose_names_are_not_ros_names_does_not_parse(key):
    with pytest.raises(Ros2NameError):
        names.parse_token(key)


def test_an_invalid_token_is_counted_and_alarmed_never_fatal(sup):
    sup.on_ros2_token(BAD_TOKEN, True, 1.0)
    snap = sup.snapshot(1.0)  # this raised ConfigError (exit 2) before
    assert snap["ros2"]["invalid_tokens"] == 1 and snap["ros2"]["nodes"] == []
    assert ("ros2_invalid_token", "@ros2_lv/0/**") in alarms(sup, 1.0)
    shown(snap)
    sup.on_ros2_token(BAD_TOKEN, False, 2.0)
    assert ("ros2_invalid_token", "@ros2_lv/0/**") not in alarms(sup, 2.0)
    assert sup.snapshot(2.0)["ros2"]["invalid_tokens"] == 1  # counted for good


def node(i, ns="/fleet"):
    return names.node_token(0, f"z{i}", 1, ns, f"n{i}")


def test_the_graph_is_bounded_the_overflow_counted_and_alarmed():
    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)
    sup.ros2 = Ros2Graph(0, max_tokens=10)
    for i in range(15):
        sup.on_ros2_token(node(i), True, 1.0)
    snap = sup.snapshot(1.0)["ros2"]
    assert (snap["tokens"], snap["overflow"], len(snap["nodes"])) == (10, 5, 10)
    assert ("ros2_graph_full", "@ros2_lv/0/**") in alarms(sup, 1.0)
    for i in range(10, 15):  # the refused ones go: the picture is complete again
        sup.on_ros2_token(node(i), False, 2.0)
    assert ("ros2_graph_full", "@ros2_lv/0/**") not in alarms(sup, 2.0)
    sup.on_ros2_token(node(20), True, 3.0)  # still full: refused again
    assert ("ros2_graph_full", "@ros2_lv/0/**") in alarms(sup, 3.0)


def test_the_graph_is_linear_in_the_tokens():
    """Work per token must not grow with the graph: Python-level calls (a deterministic
    measure, whatever the machine's speed) for 4× the tokens stay within 5× — a graph that
    rescanned every entity per token would take 16×."""
    app, arch = resolve_application("patrol")

    def calls(n):
        sup = Supervisor(arch, app, 0.0)
        tokens = [node(i, f"/robot{i % 3 + 1}") for i in range(n)]
        count = [0]

        def prof(frame, event, arg):
            if event == "call":
                count[0] += 1
        sys.setprofile(prof)
        try:
            for k in tokens:
                sup.on_ros2_token(k, True, 1.0)
        finally:
            sys.setprofile(None)
        return count[0]

    small, large = calls(300), calls(1200)
    assert large <= 5 * small, (small, large)


@pytest.mark.slow
def test_twenty_thousand_tokens_cost_bounded_memory():
    import tracemalloc
    app, arch = resolve_application("patrol")
    keys_ = [names.endpoint_token(0, f"z{i // 10}", 1, 2 + i % 10, "MP", f"/fleet{i % 50}",
                                  f"n{i // 10}", f"/fleet{i % 50}/t{i % 10}",
                                  "std_msgs/msg/String", HASH, COMMANDS) for i in range(20_000)]
    sup = Supervisor(arch, app, 0.0)
    tracemalloc.start()
    try:
        for k in keys_:
            sup.on_ros2_token(k, True, 1.0)
        grown = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    snap = sup.snapshot(1.0)["ros2"]
    assert snap["tokens"] == sup.ros2.max_tokens and snap["overflow"] == 20_000 - snap["tokens"]
    assert grown < 4_000_000, grown  # the keys are the caller's; the graph adds indexes only


@settings(max_examples=60, derandomize=True, deadline=None)
@given(st.lists(st.tuples(st.integers(0, 11), st.booleans()), max_size=60))
def test_the_incremental_indexes_equal_a_recount(events):
    """Whatever order tokens come and go in, the counters equal a count from scratch."""
    pool = [names.node_token(0, "z1", 1, "/robot1", "driver"),
            names.node_token(0, "z2", 1, "/robot1", "driver"),  # same name, another process
            names.node_token(0, "z3", 1, "/robot2/sensors", "sonar"),
            names.node_token(0, "z4", 1, "/", "tool"),
            names.node_token(1, "z5", 1, "/robot3", "other_domain"),
            BAD_TOKEN]
    for i, (kind, topic, t) in enumerate([("MP", "/robot1/odom", "nav_msgs/msg/Odometry"),
                                          ("MS", "/robot1/odom", "nav_msgs/msg/Odometry"),
                                          ("MP", "/robot1/odom", "std_msgs/msg/String"),
                                          ("MS", "/robot1/cmd_vel", "geometry_msgs/msg/Twist"),
                                          ("MP", "/chatter", "std_msgs/msg/String"),
                                          ("SS", "/srv", "std_msgs/msg/String")]):
        pool.append(names.endpoint_token(0, "z1", 1, 10 + i, kind, "/robot1", "driver", topic,
                                         t, HASH, COMMANDS))
    g = Ros2Graph(0, max_tokens=8)
    alive: list[str] = []  # held by the graph, in order
    for i, up in events:
        key = pool[i]
        g.on_token(key, up)
        try:
            e = names.parse_token(key)
        except Ros2NameError:
            continue
        if e.domain != 0:
            continue
        if up and key not in alive and len(alive) < 8:
            alive.append(key)
        elif not up and key in alive:
            alive.remove(key)
    entities = [names.parse_token(k) for k in alive]
    assert g.nodes() == sorted({e.node_name for e in entities if e.kind == "NN"})
    robots: dict = {}
    for e in entities:
        if e.kind == "NN" and e.namespace.strip("/"):
            robots.setdefault(e.namespace.strip("/").split("/")[0], set()).add(e.node_name)
    assert g.robot_nodes() == {r: sorted(v) for r, v in robots.items()}
    table: dict = {}
    for e in entities:
        if e.kind in ("MP", "MS"):
            t = table.setdefault(e.topic, {"topic": e.topic, "types": set(), "publishers": 0,
                                           "subscriptions": 0})
            t["types"].add(e.type)
            t["publishers" if e.kind == "MP" else "subscriptions"] += 1
    assert g.topics() == [{**t, "types": sorted(t["types"])} for _, t in sorted(table.items())]
    assert g.size == len(alive)


# ------------------------------------------------------------------ driver_lost

DRIVER = names.node_token(0, "z1", 1, "/robot2", "pioneer_driver")
BRIDGE = "@mrta/ros2_bridge/robot2"


def test_a_fake_node_of_a_robot_nobody_bridges_changes_nothing(sup):
    """The attack: `/robot1/fake_driver` declared for 2 s must not leave robot1 offline with
    `driver_lost` for good."""
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    fake = names.node_token(0, "zz", 1, "/robot1", "fake_driver")
    sup.on_ros2_token(fake, True, 1.0)
    sup.on_ros2_token(fake, False, 3.0)
    sup.update(3.0)
    assert states(sup, 3.0)["robot1"] == "idle" and not alarms(sup, 3.0)


def test_a_bridged_robot_is_offline_without_its_driver_until_the_bridge_goes(sup):
    sup.on_liveliness("robot2/alliance/agent", True, 0.0)
    sup.on_bridge_token(BRIDGE, True, 0.5)
    assert states(sup, 0.5)["robot2"] == "idle"  # no driver seen yet: no verdict
    sup.on_ros2_token(DRIVER, True, 1.0)
    sup.on_ros2_token(DRIVER, False, 2.0)
    assert states(sup, 2.0)["robot2"] == "offline"
    assert ("driver_lost", "robot2") in alarms(sup, 2.0)
    sup.on_bridge_token(BRIDGE, False, 3.0)  # the bridge goes: its rule goes with it
    assert states(sup, 3.0)["robot2"] == "idle" and not alarms(sup, 3.0)
    sup.on_bridge_token(BRIDGE, True, 4.0)  # a new bridge waits for a driver again
    assert states(sup, 4.0)["robot2"] == "idle" and not alarms(sup, 4.0)
    sup.on_bridge_token("@mrta/ros2_bridge/robot9", True, 4.0)  # not ours: ignored
    assert "robot9" not in states(sup, 4.0)


# ------------------------------------------------------------------ strangers

def irc(sup, robot, task, now, key_robot=None):
    sup.on_sample(sup.monitors, f"{key_robot or robot}/alliance/inter_robot_communication", IRC,
                  InterRobotCommunication(Header(robot, now, 0), task, 60.0), now)


def test_a_robot_outside_the_application_is_recognised_before_its_fields(sup):
    irc(sup, "robot9", "not a task id!", 1.0)
    assert ("unknown_robot", "robot9") in alarms(sup, 1.0)
    assert sup.counts["field_errors"] == 0  # it was only a field error before
    irc(sup, "robot9", "wander", 1.5)
    assert states(sup, 1.5) == {"robot1": "offline", "robot2": "offline", "robot3": "offline"}


def test_a_stranger_holding_a_token_is_alarmed_while_the_token_lives(sup):
    sup.on_liveliness("robot9/alliance/agent", True, 1.0)
    sup.update(1.0)
    assert ("unknown_robot", "robot9") in alarms(sup, 1.0)
    sup.update(50.0)  # far beyond unknown_expiry (10 s): the token still lives
    assert ("unknown_robot", "robot9") in alarms(sup, 50.0)
    sup.on_liveliness("robot9/alliance/agent", False, 51.0)
    sup.update(55.0)
    assert ("unknown_robot", "robot9") in alarms(sup, 55.0)
    sup.update(61.0)  # unknown_expiry after it went
    assert ("unknown_robot", "robot9") not in alarms(sup, 61.0)
    assert sup.counts["stranger_tokens"] == 1


def test_many_strangers_cost_bounded_memory(sup):
    for i in range(1000):
        for j in range(40):
            sup.on_liveliness(f"robot{1000 + i}/x{j}", True, 1.0)
    assert len(sup.unknown) == sup.MAX_UNKNOWN
    assert len(sup._stranger_tokens) <= sup.MAX_UNKNOWN
    assert all(len(v) <= sup.MAX_STRANGER_TOKENS for v in sup._stranger_tokens.values())


# ------------------------------------------------------------------ attacker bytes

def test_visible_escapes_what_a_terminal_would_obey():
    assert visible("robot1") == "robot1"
    assert visible(ESC) == "\\x1b]0;pwned\\x07\\x1b[2J"
    assert visible("\x9b31m\u202e\\x1b") == "\\x9b31m\\u202e\\\\x1b"  # C1, bidi, a forged escape
    assert visible("a" * 10, limit=4) == "aaaa…"


def test_names_from_the_network_reach_alarms_logs_and_the_view_escaped(sup, caplog):
    sup.on_lockstep((ESC, "robot1"), 1.0)
    assert ("participant_unresponsive", visible(ESC)) in alarms(sup, 1.0)
    with caplog.at_level(logging.WARNING, logger="mrta.supervisor"):
        sup.on_sample(sup.monitors, "robot1/alliance/inter_robot_communication",
                      ESC + "/Type", Twist(0.0, 0.0), 2.0)
        sup.on_sample(sup.monitors, ESC + "/alliance/inter_robot_communication", IRC,
                      InterRobotCommunication(Header("robot1", 2.0, 0), "wander", 1.0), 2.0)
        sup.on_liveliness(ESC + "/alliance/agent", True, 2.0)
    assert sup.counts["wrong_type"] == 1 and sup.counts["bad_keys"] == 2
    logged = "\n".join(r.getMessage() for r in caplog.records)
    assert "\x1b" not in logged and "\\x1b]0;pwned" in logged
    snap = sup.snapshot(2.0)
    text = shown(snap)
    assert "\x1b" not in text and "\x07" not in text
    assert all(c.isprintable() for a in snap["alarms"] for c in a["subject"])


# ------------------------------------------------------------------ the team

def make_agent(tmp_path, team=None):
    rf = write(tmp_path / "r.yaml", robot_yaml([{"task": "a", "fast": 5.0, "theta": 100.0}],
                                               spin=10.0, broadcast=5.0, tau=1.0))
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    options = AgentOptions("robot1", rf, tf, team=team)
    bus, clock = InProcBus(), ManualClock(100.0)
    agent = ALLIANCE.agent(ALLIANCE.prepare(options), bus, clock, np.random.default_rng(1))
    agent.limit_team(options.team)
    agent.start()
    return agent, bus, clock


def stranger_claims(agent, bus, clock, ticks):
    """robot9 holds an agent token and claims the task every tick (a forged teammate)."""
    for _ in range(ticks):
        now = clock.now()
        bus.publish(keys.odom("robot1"), Odometry(Header("robot1", now, 0), Pose2D(0.0, 0.0, 0.0),
                                                  Twist(0.0, 0.0)))
        bus.publish(keys.sonar("robot1"), PointCloud(Header("robot1", now, 0), ()))
        bus.publish("robot9/alliance/inter_robot_communication",
                    InterRobotCommunication(Header("robot9", now, 0), "a", 100.0))
        agent.tick_high(now)
        clock.advance(0.1)


def test_robots_off_the_team_are_ignored_and_counted(tmp_path):
    agent, bus, clock = make_agent(tmp_path, team=("robot1", "robot2", "robot3"))
    bus.declare_token("robot9/alliance/agent")
    stranger_claims(agent, bus, clock, 3)
    high = agent.coordinator.high.sets["a"]
    assert agent.team == set() and high.others == {}
    assert high.impatience == 5.0  # nobody else on the team does it: the fast rate
    assert agent.ignored_outsiders == 1 + 3  # its token, then each of its claims
    bus.declare_token("robot2/alliance/agent")  # a teammate still joins
    agent.tick_high(clock.now())
    assert agent.team == {"robot2"}


def test_without_a_team_anyone_holding_a_token_counts(tmp_path):
    """The open behaviour (no --team), documented: right on a bus only the team uses."""
    agent, bus, clock = make_agent(tmp_path)
    bus.declare_token("robot9/alliance/agent")
    stranger_claims(agent, bus, clock, 3)
    assert agent.team == {"robot9"} and agent.coordinator.high.sets["a"].impatience == 0.1


def test_a_team_must_hold_the_robot_itself(tmp_path):
    with pytest.raises(ConfigError, match="robot1 is not on its own team"):
        AgentOptions("robot1", tmp_path / "r.yaml", tmp_path / "t.yaml", team=("robot2",))
    assert AgentOptions("/robot1", tmp_path / "r", tmp_path / "t",
                        team=("/robot1", "robot2", "robot2")).team == ("robot1", "robot2")


def test_the_team_option_and_its_environment_variable(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from mrta_agent.runtime import cli
    from mrta_zenoh.architectures import TEAM_ENV

    seen = []
    monkeypatch.setattr(ALLIANCE, "run", lambda options, stop=None: seen.append(options.team))
    command = cli.agent_command(ALLIANCE, "help")
    args = ["robot1", "--robot-params", "r", "--tasks-params", "t"]
    runner = CliRunner()
    assert runner.invoke(command, args + ["--team", "robot1,/robot2"]).exit_code == 0
    assert runner.invoke(command, args, env={TEAM_ENV: "robot1,robot3"}).exit_code == 0
    assert runner.invoke(command, args, env={TEAM_ENV: ""}).exit_code == 0
    assert seen == [("robot1", "robot2"), ("robot1", "robot3"), None]
    bad = runner.invoke(command, args + ["--team", "robot1,ro bot"])
    assert bad.exit_code == 2 and "invalid robot id" in bad.output


@pytest.mark.parametrize("package, launch", [("patrol", "patrol_sim.launch"),
                                             ("patrol", "patrol.launch"),
                                             ("patrol_murdoch", "patrol_sim.launch"),
                                             ("patrol_murdoch", "patrol_murdoch.launch")])
def test_agents_launched_from_the_application_get_its_robots_as_their_team(package, launch):
    from mrta_zenoh.toolchain.launchfile import LaunchEvaluator
    from mrta_zenoh.toolchain.registry import Registry

    reg = Registry()
    nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(
        reg.find(package).path / "launch" / launch, {})
    agents = [n for n in nodes if n.type == "agent"]
    assert len(agents) == 3
    assert all(n.env.get("MRTA_TEAM") == "robot1,robot2,robot3" for n in agents)


def test_invented_keys_cannot_grow_the_live_view_without_bound(monkeypatch):
    """`mrta view` serves one Foxglove channel per key: keys come from the network, so new ones
    are refused (counted) beyond MAX_LIVE_CHANNELS, while the derived channels still go out."""
    from mrta_supervisor.live import viewer
    monkeypatch.setattr(viewer, "MAX_LIVE_CHANNELS", 3)
    schema = ("mrta.Any", "jsonschema", b'{"type": "object"}')
    with viewer.LiveChannels("127.0.0.1", 0) as live:
        for i in range(5):
            live.emit_bus(f"robot{i}/x", schema, b"{}", 1)
        live.emit_bus("robot0/x", schema, b"{}", 2)  # a known key still flows
        live.emit("/supervisor/state", schema, "json", b"{}", 3)
        assert sorted(live.channels) == ["/supervisor/state", "robot0/x", "robot1/x", "robot2/x"]
        assert live.refused == 2


def test_lockstep_rivals_and_refused_stepdones_are_alarms(sup):
    """The simulator reports other clock sources on the bus and StepDones it refused
    (mrta_zenoh.lockstep.protocol.LockstepStatus): the supervisor shows both, escaped, and clears them."""
    sup.on_lockstep((), 1.0, rivals=("ab12-x2" + ESC,), dropped=3)
    raised = alarms(sup, 1.0)
    assert ("lockstep_refused", "simulator") in raised
    assert ("clock_rival", visible("ab12-x2" + ESC)) in raised
    sup.on_lockstep((), 2.0, rivals=(), dropped=3)  # no new refusal, the rival is gone
    assert not {k for k, _ in alarms(sup, 2.0)} & {"clock_rival", "lockstep_refused"}
