"""The simulator on the bus: commands in, clock and sensors out, paced to a speed factor.

Commands that arrive between two physics steps are applied at the next step boundary, so the
simulation itself stays deterministic; only *when* a networked command lands depends on the network.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from dataclasses import dataclass

from mrta_zenoh import keys
from mrta_zenoh.bus import Bus
from mrta_zenoh.clock import CEILING, EPSILON
from mrta_zenoh.lockstep import Barrier
from mrta_zenoh.messages import Clock, Header, Odometry, Point2D, PointCloud, Pose2D, Twist

from .engine import SENSOR_EVERY, Simulation
from .messages import Bumper, Segment, World

log = logging.getLogger("mrta.sim")


def bumper_key(robot_id: str) -> str:
    return f"{robot_id}/bumper"


WORLD_KEY = "world"
WORLD_EVERY = 50  # steps: the walls go out once a simulated second (a late viewer gets them)


@dataclass
class RunStats:
    sim_time: float = 0.0
    wall_time: float = 0.0
    steps: int = 0
    commands: int = 0
    rejected_commands: int = 0
    unknown_robot_commands: int = 0
    ros2_bypass_commands: int = 0

    @property
    def real_time_factor(self) -> float:
        return self.sim_time / self.wall_time if self.wall_time > 0 else float("inf")


class SimNode:
    """Runs a Simulation against a bus. `speed`: 1 real time, k faster, 0 as fast as possible
    (at most CEILING× real time: what followers accept, mrta_zenoh.clock)."""

    def __init__(self, sim: Simulation, bus: Bus, speed: float = 1.0,
                 publish_sensors: bool = True, monotonic=time.monotonic, run_id: str = "",
                 ros2=None):
        if speed < 0:
            raise ValueError(f"speed must be ≥ 0, got {speed}")
        self.sim = sim
        self.bus = bus
        self.speed = speed
        self.run_id = run_id
        self.publish_sensors = publish_sensors
        self.stats = RunStats()
        self._monotonic = monotonic  # pacing is the one place that must follow the wall clock
        self._pending: dict[str, tuple[float, float]] = {}
        self._lock = threading.Lock()
        self._warned: set[str] = set()
        self._keys = [(keys.sonar(r), keys.odom(r), keys.ground_truth(r), bumper_key(r))
                      for r in sim.ids]
        self._sub = bus.subscribe(keys.ALL_CMD_VEL, self._on_cmd, msg_type=Twist)
        # robots served as ROS 2 robots (simulator/ros2.py): their data go out there only, and
        # only commands from there move them
        self.ros2 = ros2(self.command) if ros2 is not None else None
        self._ros2_ids = set(self.ros2.nodes) if self.ros2 is not None else set()

    def _on_cmd(self, sample) -> None:
        rid = keys.first_chunk(sample.key)
        if rid in self._ros2_ids:
            self.stats.ros2_bypass_commands += 1
            self._warn_once(rid + "/ros2", f"{rid} is a ROS 2 robot: commands on {sample.key} "
                            "are ignored (they reach it through its ROS 2 cmd_vel)")
            return
        msg = sample.message
        self.command(rid, msg.linear, msg.angular)

    def command(self, rid: str, linear: float, angular: float) -> None:
        """A velocity command for the next step boundary (our keys, or a ROS 2 driver)."""
        with self._lock:
            self._pending[rid] = (linear, angular)

    def _apply_commands(self) -> None:
        with self._lock:
            pending, self._pending = self._pending, {}
        for rid, (lin, ang) in sorted(pending.items()):  # sorted: same order every run
            if rid not in self.sim.index:
                self.stats.unknown_robot_commands += 1
                self._warn_once(rid, f"cmd_vel for {rid!r}, which is not in this simulation")
                continue
            try:
                self.sim.command(rid, lin, ang)
                self.stats.commands += 1
            except ValueError as exc:
                self.stats.rejected_commands += 1
                self._warn_once(rid + "/bad", f"{exc}; command ignored")

    def _warn_once(self, what: str, text: str) -> None:
        if what not in self._warned:
            self._warned.add(what)
            log.warning(text)

    def run(self, stop: threading.Event, duration: float | None = None,
            barrier: Barrier | None = None) -> RunStats:
        """Step until `duration` (simulated) or `stop`. With a lockstep `barrier`, each step's
        sensor data go out first, then the step, and the next step waits for every participant
        (mrta_zenoh.lockstep)."""
        sim = self.sim
        if barrier is None:
            self.bus.publish(keys.CLOCK, Clock(sim.time, self.run_id), lossy=True)
        if self.publish_sensors:
            self.publish_all()
        if barrier is not None:
            # participants follow steps; the clock (for observers) only once they are in step,
            # so that no participant starts on the clock ahead of its sensor data
            barrier.publish(sim.time)
            barrier.wait(sim.time, stop)
            self.bus.publish(keys.CLOCK, Clock(sim.time, self.run_id), lossy=True)
        wall0, sim0 = self._monotonic(), sim.time
        while not stop.is_set():
            if duration is not None and sim.time >= duration - EPSILON:
                break
            self._apply_commands()
            sim.step()
            self.bus.publish(keys.CLOCK, Clock(sim.time, self.run_id), lossy=True)
            if self.publish_sensors and sim.steps % SENSOR_EVERY == 0:
                self.publish_all()
            if sim.steps % WORLD_EVERY == 0:
                self.publish_world()
            if barrier is not None and barrier.due(sim.time):
                barrier.publish(sim.time)
                barrier.wait(sim.time, stop)
            # speed 0 ("as fast as possible") still stays under the followers' creep bound
            # (mrta_zenoh.clock.CEILING), so a follower never rejects the real clock
            ahead = (sim.time - sim0) / (self.speed or CEILING) - (self._monotonic() - wall0)
            if ahead > 0 and stop.wait(ahead):
                break
        self.stats.sim_time = sim.time - sim0
        self.stats.wall_time = self._monotonic() - wall0
        self.stats.steps = sim.steps
        return self.stats

    def publish_world(self) -> None:
        walls = tuple(Segment(*map(float, w)) for w in self.sim.world.walls)
        self.bus.publish(WORLD_KEY, World(Header("world", self.sim.time, 0), self.sim.world.name,
                                          walls), lossy=True)

    def publish_all(self) -> None:
        sim = self.sim
        t = sim.time
        reading = sim.sonar()
        pts = reading.points.tolist()
        pose, odom, twist = sim.pose.tolist(), sim.odom.tolist(), sim.odom_twist.tolist()
        vel = sim.vel.tolist()
        stalled, contacts = sim.stalled.tolist(), (sim.contacts > 0).tolist()
        collisions = sim.collisions.tolist()
        publish = functools.partial(self.bus.publish, lossy=True)  # sensor data: best effort
        for i, rid in enumerate(sim.ids):
            k_sonar, k_odom, k_truth, k_bump = self._keys[i]
            cloud = PointCloud(Header(f"{rid}/sonar", t, 0), tuple(Point2D(x, y) for x, y in pts[i]))
            odometry = Odometry(Header(f"{rid}/odom", t, 0), Pose2D(*odom[i]), Twist(*twist[i]))
            if rid in self._ros2_ids:
                self.ros2.publish(rid, odometry, cloud)
            else:
                publish(k_sonar, cloud)
                publish(k_odom, odometry)
            publish(k_truth, Odometry(Header("world", t, 0), Pose2D(*pose[i]), Twist(*vel[i])))
            publish(k_bump, Bumper(Header(rid, t, 0), stalled[i], contacts[i], collisions[i]))

    def close(self) -> None:
        self._sub.close()
        if self.ros2 is not None:
            self.ros2.close()

    def __enter__(self) -> "SimNode":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

