"""The simulation proper: pymunk physics for every robot, driven as one numpy batch.

No bus and no wall clock here: `Simulation` advances in fixed 20 ms steps when told to, so the same
seed and the same commands at the same simulated times give the same trajectories (the test of
determinism), and tests can drive it directly. `node.py` connects it to Zenoh.

Per step: commands (with watchdog, speed caps and acceleration limits) become body velocities,
written for all bodies with `pymunk.batch.set_space_bodies`; pymunk resolves collisions; poses and
velocities come back with `get_space_bodies`; odometry integrates the measured motion with a seeded
per-robot bias and per-step noise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk
import pymunk.batch as batch

from mrta_zenoh.seeds import generator

from .robot_model import RobotModel
from .sonar import ray_robots, ray_walls, sonar_origins
from .world import Pose, World

PHYSICS_HZ = 50
SENSOR_HZ = 10
DT = 1.0 / PHYSICS_HZ
SENSOR_EVERY = PHYSICS_HZ // SENSOR_HZ

_ROBOT, _WALL = 1, 2
_WALL_RADIUS = 0.02
_MOTOR_FORCE = 2000.0   # N: enough for 0.3 m/s² on 9 kg a hundred times over, bounded for contacts
_MOTOR_TORQUE = 5000.0  # N·m
_STALL_FRACTION = 0.25  # moving less than this share of the commanded speed while pushing = stall


@dataclass(frozen=True)
class SonarReading:
    ranges: np.ndarray   # (N, K) metres, noisy, clipped to [min, max]; max means no echo
    points: np.ndarray   # (N, K, 2) robot frame, metres


class Simulation:
    def __init__(self, world: World, robots: dict[str, Pose], model: RobotModel | None = None,
                 seed: int = 0, record_trails: bool = False):
        if not robots:
            raise ValueError("a simulation needs at least one robot")
        self.world = world
        self.model = model or RobotModel()
        self.ids = list(robots)
        self.index = {rid: i for i, rid in enumerate(self.ids)}
        # the world's noise: the run's root stream (mrta_zenoh.seeds, the one derivation)
        self.rng = generator(seed)
        self.sonars = self.model.sonar_poses()
        self.time = 0.0
        self.steps = 0
        n = len(self.ids)

        self.space = pymunk.Space()
        self.space.iterations = 10
        for x1, y1, x2, y2 in world.walls:
            seg = pymunk.Segment(self.space.static_body, (x1, y1), (x2, y2), _WALL_RADIUS)
            seg.collision_type = _WALL
            seg.friction = 0.0
            self.space.add(seg)
        moment = pymunk.moment_for_circle(self.model.mass, 0, self.model.radius)
        self._robot_of: dict[int, int] = {}    # pymunk body id → robot index
        self._control_of: dict[int, int] = {}  # kinematic control body id → robot index
        for i, rid in enumerate(self.ids):
            pose = robots[rid]
            body = pymunk.Body(self.model.mass, moment)
            body.position = (pose.x, pose.y)
            body.angle = pose.theta
            shape = pymunk.Circle(body, self.model.radius)
            shape.collision_type = _ROBOT
            shape.friction = 0.0
            # The motors act through a kinematic "control body" joined by velocity-only joints
            # with bounded force (pymunk's tank demo): contacts beat the motors, so a robot
            # pushing a wall stalls instead of being teleported into it.
            control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            control.position = body.position
            control.angle = pose.theta  # the gear joint holds the two angles together
            pivot = pymunk.PivotJoint(control, body, (0, 0), (0, 0))
            pivot.max_bias = 0.0
            pivot.max_force = _MOTOR_FORCE
            gear = pymunk.GearJoint(control, body, 0.0, 1.0)
            gear.error_bias = 0.0
            gear.max_bias = 1.2
            gear.max_force = _MOTOR_TORQUE
            self.space.add(body, shape, control, pivot, gear)
            self._robot_of[body.id] = i
            self._control_of[control.id] = i
        self.space.on_collision(_ROBOT, _WALL, begin=self._begin, separate=self._separate)
        self.space.on_collision(_ROBOT, _ROBOT, begin=self._begin, separate=self._separate)

        self._buf = batch.Buffer()
        self._fields_get = (batch.BodyFields.POSITION | batch.BodyFields.ANGLE
                            | batch.BodyFields.VELOCITY | batch.BodyFields.ANGULAR_VELOCITY)
        self._fields_set = batch.BodyFields.VELOCITY | batch.BodyFields.ANGULAR_VELOCITY
        self.pose = np.array([[robots[r].x, robots[r].y, robots[r].theta] for r in self.ids],
                             dtype=float)
        self._layout()
        self._read()
        self._last_pose = self.pose.copy()
        self._cmd_world = np.zeros((n, 3))
        self._vmax = np.array([self.model.max_linear, self.model.max_angular])
        self._dv = np.array([self.model.linear_accel, self.model.angular_accel]) * DT
        self.cmd = np.zeros((n, 2))          # commanded linear, angular
        self.cmd_time = np.full(n, -np.inf)  # simulated time of the last command
        self.vel = np.zeros((n, 2))          # what the motors deliver after acceleration limits
        self.odom = self.pose.copy()
        self.odom_twist = np.zeros((n, 2))
        self._odom_bias = np.stack([
            1.0 + self.rng.normal(0.0, self.model.odom_scale_sigma, n),
            1.0 + self.rng.normal(0.0, self.model.odom_turn_sigma, n)], axis=1)
        self.stalled = np.zeros(n, dtype=bool)
        self.contacts = np.zeros(n, dtype=int)
        self.collisions = np.zeros(n, dtype=int)
        self.distance = np.zeros(n)
        self.trails: list[np.ndarray] | None = [self.pose[:, :2].copy()] if record_trails else None

    # ------------------------------------------------------------------ commands and stepping

    def command(self, robot_id: str, linear: float, angular: float) -> None:
        """Set a robot's velocity command, stamped with the current simulated time."""
        i = self.index[robot_id]
        if not (math.isfinite(linear) and math.isfinite(angular)):
            raise ValueError(f"non-finite command for {robot_id}: {linear}, {angular}")
        self.cmd[i] = (linear, angular)
        self.cmd_time[i] = self.time

    def step(self) -> None:
        """One 20 ms physics step; odometry, stall and trails update every sensor period."""
        m = self.model
        fresh = (self.time - self.cmd_time) <= m.watchdog
        target = np.where(fresh[:, None], self.cmd, 0.0)
        np.minimum(target, self._vmax, out=target)
        np.maximum(target, -self._vmax, out=target)
        change = target - self.vel
        np.minimum(change, self._dv, out=change)
        np.maximum(change, -self._dv, out=change)
        self.vel += change

        th = self.pose[:, 2]
        out = self._cmd_world
        np.multiply(self.vel[:, 0], np.cos(th), out=out[:, 0])
        np.multiply(self.vel[:, 0], np.sin(th), out=out[:, 1])
        out[:, 2] = self.vel[:, 1]
        self._write(out)
        self.space.step(DT)
        self.steps += 1
        self.time = self.steps * DT  # no float drift: time is always an exact multiple of DT
        self._read()
        if self.steps % SENSOR_EVERY == 0:
            self._sensor_period()

    def advance(self, seconds: float) -> None:
        for _ in range(int(round(seconds * PHYSICS_HZ))):
            self.step()

    # ------------------------------------------------------------------------------ sensors

    def sonar(self) -> SonarReading:
        m = self.model
        origins, dirs = sonar_origins(self.pose, self.sonars)
        k = len(self.sonars)
        half = m.sonar_half_angle
        ranges = np.minimum(
            ray_walls(origins, dirs, self.world.walls, m.sonar_max, half, k),
            ray_robots(origins, dirs, self.pose[:, :2], m.radius, k, m.sonar_max, half,
                       axes=self.sonars[:, 2]))
        noise = self.rng.normal(0.0, 1.0, len(ranges))  # drawn every time: keeps the seed stream
        echo = np.isfinite(ranges)
        ranges = np.where(echo, ranges + noise * (m.sonar_noise * np.where(echo, ranges, 0.0)
                                                  + m.sonar_noise_floor), m.sonar_max)
        ranges = np.clip(ranges, m.sonar_min, m.sonar_max).reshape(-1, k)
        s = self.sonars
        pts = np.stack([s[None, :, 0] + ranges * np.cos(s[None, :, 2]),
                        s[None, :, 1] + ranges * np.sin(s[None, :, 2])], axis=-1)
        return SonarReading(ranges, pts)

    # ------------------------------------------------------------------------------ internals

    def _sensor_period(self) -> None:
        """Odometry as the robot's firmware reports it (10 Hz), stall, distance and trails."""
        before, self._last_pose = self._last_pose, self.pose.copy()
        moved = self.pose[:, :2] - before[:, :2]
        dth = _wrap(self.pose[:, 2] - before[:, 2])
        mid = before[:, 2] + dth / 2.0
        ds = moved[:, 0] * np.cos(mid) + moved[:, 1] * np.sin(mid)
        period = SENSOR_EVERY * DT
        self.distance += np.hypot(moved[:, 0], moved[:, 1])
        want = np.abs(self.vel[:, 0]) * period
        self.stalled = (want > 0.02 * period) & (np.abs(ds) < _STALL_FRACTION * want) & \
            (self.contacts > 0)
        noise = self.rng.normal(0.0, self.model.odom_step_sigma, (len(ds), 2))
        ds_m = ds * (self._odom_bias[:, 0] + noise[:, 0])
        dth_m = dth * (self._odom_bias[:, 1] + noise[:, 1])
        mid = self.odom[:, 2] + dth_m / 2.0
        self.odom[:, 0] += ds_m * np.cos(mid)
        self.odom[:, 1] += ds_m * np.sin(mid)
        self.odom[:, 2] = _wrap(self.odom[:, 2] + dth_m)
        self.odom_twist[:, 0] = ds_m / period
        self.odom_twist[:, 1] = dth_m / period
        if self.trails is not None:
            self.trails.append(self.pose[:, :2].copy())

    def _layout(self) -> None:
        """Find our bodies in pymunk's batch order, which also lists the static and control bodies.

        Batch writes set every body, so the write array starts as what was last read and only
        the control bodies' velocities change (robots keep their solved velocities)."""
        self._buf.clear()
        batch.get_space_bodies(self.space, batch.BodyFields.BODY_ID, self._buf)
        ids = [int(b) for b in np.frombuffer(self._buf.int_buf(), dtype=np.uintp)]
        robot_slots = [k for k, b in enumerate(ids) if b in self._robot_of]
        control_slots = [k for k, b in enumerate(ids) if b in self._control_of]
        self._robot_slots = _index(robot_slots)
        self._robot_rows = _index([self._robot_of[ids[k]] for k in robot_slots])
        self._control_slots = _index(control_slots)
        self._control_rows = _index([self._control_of[ids[k]] for k in control_slots])
        # Writes go through their own Buffer that borrows this array for good: a Buffer that
        # also serves reads would realloc() numpy's memory (heap corruption, found the hard way).
        # It holds every body's velocity as last read (_read), so that a write changes only
        # the control bodies' (robots keep their solved velocities).
        self._wbuf = np.zeros((len(ids), 3))
        self._set_buf = batch.Buffer()
        self._set_buf.set_float_buf(self._wbuf.reshape(-1))

    def _write(self, vel: np.ndarray) -> None:
        self._wbuf[self._control_slots] = vel[self._control_rows]
        batch.set_space_bodies(self.space, self._fields_set, self._set_buf)

    def _read(self) -> None:
        self._buf.clear()
        batch.get_space_bodies(self.space, self._fields_get, self._buf)
        # a view of the Buffer's memory, used up before the Buffer is touched again
        state = np.frombuffer(self._buf.float_buf(), dtype=np.float64).reshape(-1, 6)
        self._wbuf[:] = state[:, 3:6]
        data = state[self._robot_slots]
        self.pose[self._robot_rows, 0:2] = data[:, 0:2]
        self.pose[self._robot_rows, 2] = _wrap(data[:, 2])

    def _begin(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        for shape in arbiter.shapes:
            i = self._robot_of.get(shape.body.id) if shape.body is not None else None
            if i is not None:
                self.contacts[i] += 1
                self.collisions[i] += 1

    def _separate(self, arbiter: pymunk.Arbiter, space: pymunk.Space, data: object) -> None:
        for shape in arbiter.shapes:
            i = self._robot_of.get(shape.body.id) if shape.body is not None else None
            if i is not None and self.contacts[i] > 0:
                self.contacts[i] -= 1


def _index(rows: list[int]) -> slice | np.ndarray:
    """Rows as a slice when evenly spaced (pymunk lists each robot's body and control body in
    turn: every other row), else as an index array. Same rows either way; a slice reads a view
    instead of gathering a copy, ≈ 5 % of a step at 1,000 robots."""
    if len(rows) > 1:
        stride = rows[1] - rows[0]
        if stride > 0 and rows == list(range(rows[0], rows[-1] + 1, stride)):
            return slice(rows[0], rows[-1] + 1, stride)
    elif len(rows) == 1:
        return slice(rows[0], rows[0] + 1)
    return np.array(rows, dtype=np.intp)


def _wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2.0 * np.pi) - np.pi
