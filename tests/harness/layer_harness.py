"""Run one patrol layer against the simulator in-process, on simulated time (no network).

The layer gets a real AgentContext over an in-process bus; sensor messages are built from the
simulation exactly as `mrta sim` publishes them and handed to the layer's sensors.
"""

from __future__ import annotations

import numpy as np

from mrta_zenoh import keys
from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
from mrta_agent.runtime.builtin import OdometrySensor, PointCloudSensor
from mrta_agent.runtime.params import SensorParams, load_layers_params
from mrta_agent.runtime.plugins import AgentContext, declared_sections
from mrta_simulator.engine import DT, SENSOR_EVERY, Simulation
from tests.harness.helpers import PATROL

LAYERS_FILE = PATROL / "config" / "layers_alliance_params.yaml"


def typed_sections(*classes, layers_file=LAYERS_FILE) -> dict:
    """The layers file's sections as the given plugin classes declare them (as the agent does)."""
    doc = load_layers_params(layers_file)
    return {(name, kind): doc.convert((name,), kind)
            for cls in classes for name, kind in declared_sections(cls).items()}


class LayerRun:
    def __init__(self, sim: Simulation, robot: str, layer_cls, seed: int = 0,
                 task_id: str | None = None, instance=None):
        """`instance`: the robot's instance document (ctx.instance: a delivery layer's)."""
        self.sim, self.robot = sim, robot
        self.clock = ManualClock(0.0)
        self.net = InProcNetwork()
        self.bus = InProcBus(self.net)
        self.sonar = PointCloudSensor(SensorParams("alliance/point_cloud", "sonar", 1.0, 1.0))
        self.odom = OdometrySensor(SensorParams("alliance/odometry", "odom", 1.0, 1.0))
        self.ctx = AgentContext(robot, self.bus, self.clock, np.random.default_rng(seed),
                                {"sonar": self.sonar, "odom": self.odom}, typed_sections(layer_cls),
                                instance=instance)
        self.bus.subscribe(keys.cmd_vel(robot), self._on_cmd, msg_type=Twist)
        self.layer = layer_cls()
        self.layer.task_id = task_id  # as the agent's loader does
        self.layer.setup(self.ctx)
        self.i = sim.index[robot]

    def _on_cmd(self, sample) -> None:
        self.sim.command(self.robot, sample.message.linear, sample.message.angular)

    def feed(self) -> None:
        sim, i, t = self.sim, self.i, self.sim.time
        pts = sim.sonar().points[i]
        self.sonar.on_message(PointCloud(Header(self.robot, t, 0),
                                         tuple(Point2D(float(x), float(y)) for x, y in pts)), t)
        self.odom.on_message(Odometry(Header(self.robot, t, 0), Pose2D(*map(float, sim.odom[i])),
                                      Twist(*map(float, sim.odom_twist[i]))), t)

    def run(self, seconds: float, each=None) -> None:
        self.feed()
        self.layer.on_activate(self.sim.time)
        for _ in range(int(round(seconds / DT))):
            self.sim.step()
            self.clock.set(self.sim.time)
            if self.sim.steps % SENSOR_EVERY == 0:
                self.feed()
                self.layer.step(self.sim.time, SENSOR_EVERY * DT)
                if each:
                    each(self)
        self.layer.on_deactivate(self.sim.time)

    def close(self) -> None:
        self.bus.close()
