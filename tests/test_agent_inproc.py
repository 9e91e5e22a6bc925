"""The agent wired to the in-process bus on a manual clock: inputs, outputs and robustness."""

import numpy as np

from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.codec import encoding_for

from mrta_zenoh.messages import Header, Odometry, PointCloud, Pose2D, Twist
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.runtime.host import AgentOptions
from mrta_agent.runtime.plugins import Layer
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write


class DriveLayer(Layer):
    """A test layer: drives forward while active."""

    def step(self, now, dt):
        self.ctx.publish_cmd(0.3, 0.0)


def make(tmp_path, sets, layers=None):
    rf = write(tmp_path / "r.yaml", robot_yaml(sets, spin=10.0, broadcast=5.0, tau=1.0))
    tf = write(tmp_path / "t.yaml", tasks_yaml([s["task"] for s in sets], layers))
    bus, clock = InProcBus(), ManualClock(100.0)
    agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions("robot1", rf, tf)), bus, clock,
                           np.random.default_rng(1))
    agent.start()
    return agent, bus, clock


def feed(bus, clock, robot="robot1"):
    bus.publish(keys.odom(robot), Odometry(Header(robot, clock.now(), 0), Pose2D(0.0, 0.0, 0.0), Twist(0.0, 0.0)))
    bus.publish(keys.sonar(robot), PointCloud(Header(robot, clock.now(), 0), ()))


def step(agent, bus, clock, n, fresh=True):
    for _ in range(n):
        if fresh:
            feed(bus, clock)
        agent.tick_high(clock.now())
        agent.step_layers(clock.now(), 0.1)
        clock.advance(0.1)


def test_activation_broadcasts_and_drives_the_layer(tmp_path):
    agent, bus, clock = make(tmp_path, [{"task": "a", "fast": 25.0}],
                             {"a": ["tests.test_agent_inproc:DriveLayer"]})
    irc, cmds, mot = [], [], []
    bus.subscribe("robot1/alliance/inter_robot_communication", irc.append)
    bus.subscribe("robot1/cmd_vel", cmds.append)
    bus.subscribe("robot1/alliance/motivation/a", mot.append)
    step(agent, bus, clock, 4)  # θ=100 / 25 → active on the 4th tick
    assert agent.coordinator.high.active_task == "a"
    assert [s.message.motivation for s in mot] == [25.0, 50.0, 75.0, 100.0]
    assert irc and irc[0].message.task_id == "a" and irc[0].message.header.frame_id == "robot1"
    assert cmds[-1].message == Twist(0.3, 0.0)
    step(agent, bus, clock, 10)
    # 5 Hz broadcasts over 1.4 s of activity
    assert len(irc) in (6, 7, 8)


def test_stalled_sensor_makes_behaviours_inapplicable_and_stops_the_robot(tmp_path):
    agent, bus, clock = make(tmp_path, [{"task": "a", "fast": 50.0}],
                             {"a": ["tests.test_agent_inproc:DriveLayer"]})
    cmds = []
    bus.subscribe("robot1/cmd_vel", cmds.append)
    step(agent, bus, clock, 3)
    assert agent.coordinator.high.active_task == "a"
    step(agent, bus, clock, 15, fresh=False)  # sensor timeout 1 s
    assert agent.coordinator.high.active_task is None
    assert cmds[-1].message == Twist(0.0, 0.0)
    assert agent.coordinator.history[-1][1].reason == "inapplicable"


def test_ignores_own_broadcasts_mismatched_frame_ids_and_malformed_samples(tmp_path):
    agent, bus, clock = make(tmp_path, [{"task": "a", "fast": 1.0}])
    bus.publish("robot1/alliance/inter_robot_communication",
                InterRobotCommunication(Header("robot1", 0.0, 0), "a", 10.0))
    bus.publish("robot2/alliance/inter_robot_communication",
                InterRobotCommunication(Header("robot7", 0.0, 0), "a", 10.0))
    bus.publish_raw("robot2/alliance/inter_robot_communication",
                    encoding_for("alliance_msgs/InterRobotCommunication"), b"\x93garbage")
    step(agent, bus, clock, 3)
    assert agent.ignored_own == 1 and agent.ignored_mismatch == 1
    assert bus.stats["malformed"] == 1
    assert agent.coordinator.high.sets["a"].others == {}
    assert agent.coordinator.high.sets["a"].impatience == 1.0  # nobody else is doing it: fast


def test_another_robots_broadcast_slows_impatience(tmp_path):
    agent, bus, clock = make(tmp_path, [{"task": "a", "fast": 5.0, "theta": 100.0}])
    bus.declare_token("robot2/alliance/agent")  # a teammate: its agent is alive
    for _ in range(3):
        bus.publish("/robot2/alliance/inter_robot_communication".strip("/"),
                    InterRobotCommunication(Header("/robot2", clock.now(), 0), "a", 100.0))
        step(agent, bus, clock, 1)
    # slow = θ / (expected · ρ) = 100 / (100 · 10) = 0.1 per tick
    assert agent.coordinator.high.sets["a"].impatience == 0.1


def test_broadcasts_from_robots_without_an_agent_token_are_ignored(tmp_path):
    """A forged robot9 (no agent token) doing the task cannot slow anybody down."""
    agent, bus, clock = make(tmp_path, [{"task": "a", "fast": 5.0, "theta": 100.0}])
    for _ in range(3):
        bus.publish("robot9/alliance/inter_robot_communication",
                    InterRobotCommunication(Header("robot9", clock.now(), 0), "a", 100.0))
        step(agent, bus, clock, 1)
    assert agent.ignored_strangers == 3 and agent.coordinator.high.sets["a"].others == {}
    assert agent.coordinator.high.sets["a"].impatience == 5.0


def test_absurd_expected_durations_are_refused_and_counted(tmp_path):
    agent, bus, clock = make(tmp_path, [{"task": "a", "fast": 5.0, "theta": 100.0}])
    bus.declare_token("robot2/alliance/agent")
    bus.publish("robot2/alliance/inter_robot_communication",
                InterRobotCommunication(Header("robot2", clock.now(), 0), "a", 1e300))
    step(agent, bus, clock, 2)
    assert agent.refused == 1 and agent.coordinator.high.sets["a"].impatience == 5.0


class DrawingLayer(DriveLayer):
    draws = True


def test_a_plugin_that_draws_gets_its_stream_at_setup_and_one_that_does_not_never(tmp_path):
    """The robot's lazy stream is made at setup when a plugin says it draws (so numpy loads
    before the run's first step, not inside a tick), and stays unmade when none does."""
    from mrta_zenoh.seeds import robot_rng

    for layer, made in (("DriveLayer", False), ("DrawingLayer", True)):
        rf = write(tmp_path / "r.yaml", robot_yaml([{"task": "a", "fast": 25.0}], spin=10.0, broadcast=5.0,
                                                    tau=1.0))
        tf = write(tmp_path / "t.yaml", tasks_yaml(["a"], {"a": [f"tests.test_agent_inproc:{layer}"]}))
        rng = robot_rng(3, "robot1")
        agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions("robot1", rf, tf)), InProcBus(),
                               ManualClock(0.0), rng)
        assert "not yet drawn" in repr(rng)
        agent.start()
        assert ("not yet drawn" not in repr(rng)) is made, layer
