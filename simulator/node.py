"""The simulator on the bus: commands in, clock and sensors out, paced to a speed factor.

Commands that arrive between two physics steps are applied at the next step boundary, so the
simulation itself stays deterministic; only *when* a networked command lands depends on the network.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass

import numpy as np

from mrta_zenoh import keys
from mrta_zenoh.bus import Bus
from mrta_zenoh.clock import CEILING, EPSILON
from mrta_zenoh.lifecycle import Closing
from mrta_zenoh.lockstep.barrier import Barrier
from mrta_zenoh.messages import Clock, Header, Twist

from .engine import SENSOR_EVERY, Simulation
from .messages import Segment, World
from .wire import SONAR, ODOM, SensorWire, bumper_key, sample_messages

# bumper_key is part of this module's interface (simulator/secure_role.py, tests' processes)
__all__ = ["SimNode", "RunStats", "WORLD_KEY", "WORLD_EVERY", "bumper_key"]

log = logging.getLogger("mrta.sim")

WORLD_KEY = "world"
WORLD_EVERY = 50  # steps: the walls go out once a simulated second (a late viewer gets them)
# Sensor periods between two bumper samples of a robot whose contact state did not change: a
# bumper goes out when it changes and, as a heartbeat, every simulated second.
BUMPER_EVERY = 10
# In lockstep the clock is for observers only (participants move with steps and ignore it), so
# it goes out once a sensor period, at every step where the barrier stops and at the step after
# it, not at every physics step: 100 agents each took 50 clock samples a simulated second for
# nothing (5,000 Python callbacks, and as many deliveries by the router), about 17 % of what
# each heard. The step after a stop: a recorder on simulated time (SimLogTime) logs
# a sample at the latest clock it has heard, and what the agents said at a stop can reach it
# after the next clock — were that the next sensor period, a run's last words before its end
# would be logged at the end and fall out of its message counts (two runs of one seed then
# differed by 2 of 7,200 messages in CI), where the next physics step keeps them inside, as
# before. A free-running simulator still sends it every step: followers move with it.
LOCKSTEP_CLOCK_EVERY = SENSOR_EVERY


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


class SimNode(Closing):
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
        self._sub = bus.subscribe(keys.ALL_CMD_VEL, self._on_cmd, msg_type=Twist)
        # robots served as ROS 2 robots (simulator/ros2.py): their data go out there only, and
        # only commands from there move them
        self.ros2 = ros2(self.command) if ros2 is not None else None
        self._ros2_ids = set(self.ros2.nodes) if self.ros2 is not None else set()
        self._ros2_rows = [(i, rid) for i, rid in enumerate(sim.ids) if rid in self._ros2_ids]
        self._wire: SensorWire | None = None  # built on the first sensor period
        self._batch = None
        self._sent_bumper: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    def _on_cmd(self, sample) -> None:
        rid = keys.first_chunk(sample.key)
        if rid in self._ros2_ids:
            # the robot's own agent publishes here in normal use, and the bridge carries those
            # commands to its ROS 2 cmd_vel: counted, said at debug level, never a warning
            self.stats.ros2_bypass_commands += 1
            if rid + "/ros2" not in self._warned:
                self._warned.add(rid + "/ros2")
                log.debug("%s is a ROS 2 robot: commands on %s go to it through the bridge, "
                          "not from here", rid, sample.key)
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
        self.publish_world()  # with the first sensor data: a viewer's first scene has walls
        if self.publish_sensors:
            self.publish_all()
        if barrier is not None:
            # participants follow steps; the clock (for observers) only once they are in step,
            # so that no participant starts on the clock ahead of its sensor data
            barrier.publish(sim.time)
            barrier.wait(sim.time, stop)
            self.bus.publish(keys.CLOCK, Clock(sim.time, self.run_id), lossy=True)
        wall0, sim0 = self._monotonic(), sim.time
        stopped = barrier is not None  # the barrier stopped at the step before this one
        while not stop.is_set():
            if duration is not None and sim.time >= duration - EPSILON:
                break
            self._apply_commands()
            sim.step()
            stop_here = barrier is not None and barrier.due(sim.time)
            if barrier is None or stop_here or stopped or sim.steps % LOCKSTEP_CLOCK_EVERY == 0:
                self.bus.publish(keys.CLOCK, Clock(sim.time, self.run_id), lossy=True)
            stopped = stop_here
            if self.publish_sensors and sim.steps % SENSOR_EVERY == 0:
                self.publish_all()
            if sim.steps % WORLD_EVERY == 0:
                self.publish_world()
            if stop_here:
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
        """One sensor period: sonar, odometry and ground truth of every robot, and the bumpers
        that changed (all of them once a simulated second), written straight from the
        simulation's arrays (simulator/wire.py) and sent as one batch; a ROS 2 robot's sonar
        and odometry go to its driver instead (as message objects).

        Why a bumper goes out on change: at 1,000 robots the four samples of every
        robot are 40,000 puts a simulated second, and the puts, not the physics, set the pace.
        A bumper is an event stream (kobuki's BumperEvent is sent on change only) whose
        `collisions` is a running count, so a consumer that misses a sample (best effort) has
        the right count from the next one; the heartbeat tells a late joiner within a second.
        A period's samples are a function of the simulated time, so a run still replays bit for
        bit."""
        sim = self.sim
        reading = sim.sonar()
        if self._wire is None:
            # best effort, as all sensor data: a stopped observer must not slow the world
            self._wire = SensorWire(sim.ids, len(sim.sonars), omit=self._ros2_ids)
            self._batch = self.bus.declare_batch(self._wire.keys, self._wire.encodings,
                                                 lossy=True)
        contact = sim.contacts > 0
        rows = self._bumper_rows(sim.stalled, contact, sim.collisions,
                                 (sim.steps // SENSOR_EVERY) % BUMPER_EVERY == 0)
        for i, rid in self._ros2_rows:
            msgs = sample_messages(rid, sim.time, reading.points[i].tolist(), sim.odom[i].tolist(),
                                   sim.odom_twist[i].tolist(), sim.pose[i].tolist(),
                                   sim.vel[i].tolist(), bool(sim.stalled[i]), bool(contact[i]),
                                   int(sim.collisions[i]))
            self.ros2.publish(rid, msgs[ODOM], msgs[SONAR])
        self._batch.publish(self._wire.encode(sim.time, reading.points, sim.odom,
                                              sim.odom_twist, sim.pose, sim.vel, sim.stalled,
                                              contact, sim.collisions), rows)

    def _bumper_rows(self, stalled: np.ndarray, contact: np.ndarray, collisions: np.ndarray,
                     heartbeat: bool) -> list[int] | None:
        """The batch rows to send this period: None (all) on a heartbeat, else every row but
        the bumpers whose (stalled, contact, collisions) did not change since they last went
        out."""
        before, now = self._sent_bumper, (stalled.copy(), contact.copy(), collisions.copy())
        if heartbeat or before is None:
            self._sent_bumper = now
            return None
        changed = (before[0] != now[0]) | (before[1] != now[1]) | (before[2] != now[2])
        mask = np.ones(len(self._wire.keys), dtype=bool)
        mask[self._wire.bump_rows] = changed
        for old, new in zip(before, now):
            old[changed] = new[changed]
        return np.flatnonzero(mask).tolist()

    def close(self) -> None:
        self._sub.close()
        if self.ros2 is not None:
            self.ros2.close()


