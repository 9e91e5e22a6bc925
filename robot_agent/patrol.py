"""The patrol application's plugins (dissertation §4.2): wander, border protection, report.

All three read the sonar as the simulator (or RosAria) publishes it: points in the robot frame,
metres; a point at the maximum range means "no echo". They never see the world map: a layer
knows only what its sensors tell it, as on the real robot.

* `wander`: keeps moving through open space; slows down as the way ahead closes, turns towards
  the more open side, and turns in place (committing to one direction) when blocked.
* `border_protection`: a PD wall follower on the side and diagonal sonars — distance error from
  the perpendicular beam, heading error from the line through the perpendicular and diagonal
  echoes — that turns at inner corners and curves back to a wall it lost at outer ones, so it
  goes round the whole perimeter (the original was stubbed to spin in place).
* `report`: drives to the report point, then publishes a team report on `robotN/patrol/report`
  (distance covered, share of the border visited, time each robot spent on each task) — made
  from what every robot broadcasts on the bus, like a patrol leader's log.
* evaluators: `wall_in_range` (border protection is applicable once a wall is within reach) and
  `report_due` (a report is due when nobody has published one for `Report/period` seconds).
"""

from __future__ import annotations

import math
import threading
from dataclasses import field

from mrta_zenoh import keys
from mrta_zenoh.geometry import rectangle_cells
from mrta_zenoh.messages import (
    Header, InterRobotCommunication, Message, Odometry, PointCloud, message,
)

from .plugins import AgentContext, Layer, SensoryEvaluator

NO_ECHO = 4.85  # m from the robot centre: beyond this a point is the sensor's "no echo"


@message("patrol_msgs/TaskTime")
class TaskTime(Message):
    robot_id: str = ""
    task_id: str = ""
    seconds: float = 0.0


@message("patrol_msgs/Report")
class Report(Message):
    header: Header = field(default_factory=Header)
    distance: float = 0.0          # metres covered by the whole team
    border_covered: float = 0.0    # share of the border's 0.5 m cells some robot came near
    task_times: tuple[TaskTime, ...] = ()


# ------------------------------------------------------------------------------ sonar view

class SonarView:
    """Echo points of the latest scan in polar form, with sector queries."""

    def __init__(self, cloud: PointCloud | None):
        self.points: list[tuple[float, float, float, float]] = []  # (x, y, r, angle)
        if cloud is None:
            return
        for p in cloud.points:
            r = math.hypot(p.x, p.y)
            if r < NO_ECHO:
                self.points.append((p.x, p.y, r, math.atan2(p.y, p.x)))

    def nearest(self, lo_deg: float, hi_deg: float) -> float:
        lo, hi = math.radians(lo_deg), math.radians(hi_deg)
        return min((r for _, _, r, a in self.points if lo <= a <= hi), default=math.inf)

    def in_sector(self, lo_deg: float, hi_deg: float) -> list[tuple[float, float]]:
        lo, hi = math.radians(lo_deg), math.radians(hi_deg)
        return [(x, y) for x, y, _, a in self.points if lo <= a <= hi]


def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


class _SonarLayer(Layer):
    def sonar(self, now: float) -> SonarView | None:
        s = self.ctx.sensors.get("sonar")
        if s is None or not s.is_up_to_date(now):
            return None
        return SonarView(s.latest)

    def pose(self, now: float) -> tuple[float, float, float] | None:
        s = self.ctx.sensors.get("odom")
        if s is None or not s.is_up_to_date(now) or not isinstance(s.latest, Odometry):
            return None
        p = s.latest.pose
        return p.x, p.y, p.theta


def avoid(view: SonarView, speed: float, safe: float, turn: float, state: dict,
          bias: float = 0.0) -> tuple[float, float]:
    """Obstacle avoidance shared by wander and report: (linear, angular) for this scan."""
    front = view.nearest(-35, 35)
    left, right = view.nearest(35, 100), view.nearest(-100, -35)
    if front < safe:
        if state.get("turn") is None:  # commit, or it dithers in a corner
            state["turn"] = 1.0 if min(left, 4.0) >= min(right, 4.0) else -1.0
        return 0.0, turn * state["turn"]
    state["turn"] = None
    slow = _clip((front - safe) / 1.2, 0.25, 1.0)
    w = 0.5 * (min(left, 3.0) - min(right, 3.0)) / 3.0 + bias
    if left < 0.55:
        w -= 0.6
    if right < 0.55:
        w += 0.6
    return speed * slow, _clip(w, -turn, turn)


class Wander(_SonarLayer):
    params_section = "Wander"

    def on_activate(self, now: float) -> None:
        self.state: dict = {}
        self.drift = 0.0

    def step(self, now: float, dt: float) -> None:
        view = self.sonar(now)
        if view is None:
            self.ctx.publish_cmd(0.0, 0.0)  # blind: stand still
            return
        # a slowly varying seeded drift so the robot explores instead of tracing one loop
        self.drift = 0.9 * self.drift + 0.1 * float(self.ctx.rng.normal(0.0, 0.6))
        v, w = avoid(view, float(self.params.get("speed", 0.5)),
                     float(self.params.get("safe_distance", 0.8)),
                     float(self.params.get("turn_rate", 0.8)), self.state, bias=self.drift)
        self.ctx.publish_cmd(v, w)


class BorderProtection(_SonarLayer):
    params_section = "BorderProtection"

    def on_activate(self, now: float) -> None:
        self.side = -1.0 if str(self.params.get("side", "right")) == "right" else 1.0
        self.lost_for = 0.0
        self.had_wall = False
        self._avoid: dict = {}

    def step(self, now: float, dt: float) -> None:
        view = self.sonar(now)
        if view is None:
            self.ctx.publish_cmd(0.0, 0.0)
            return
        v, w = self.command(view, dt, self.pose(now))
        self.ctx.publish_cmd(v, w)

    def command(self, view: SonarView, dt: float,
                pose: tuple[float, float, float] | None = None) -> tuple[float, float]:
        d_set = float(self.params.get("distance", 1.0))
        speed = float(self.params.get("speed", 0.4))
        kp, kd = float(self.params.get("kp", 1.5)), float(self.params.get("kd", 2.0))
        reach = 2.5 * d_set  # echoes further than this on the side are not "the wall"
        s = self.side  # −1: wall on the right; turning away from it is +angular
        front = view.nearest(-30, 30)
        if front < d_set + 0.35:
            return 0.05, -s * 0.9  # inner corner: turn away from the wall side
        # While following, any wall beside us is the border (odometry drifts too much after a lap
        # to check it against the border rectangle); when picking up a wall, it must be the border.
        check = (lambda p: True) if self.had_wall else (lambda p: self._on_border(p, pose))
        lo, hi = (-100, -75) if s < 0 else (75, 100)
        perp = [p for p in view.in_sector(lo, hi) if abs(p[1]) < reach and check(p)]
        dlo, dhi = (-65, -35) if s < 0 else (35, 65)
        diag = [p for p in view.in_sector(dlo, dhi) if math.hypot(*p) < reach * 1.3]
        if not perp:
            # only the perpendicular beam establishes "the wall is beside me"; a diagonal echo
            # alone is a wall ahead, which the inner-corner rule above deals with
            self.lost_for += dt
            if self.had_wall and self.lost_for < 3.0:
                # just lost it: an outer corner; curve round it towards the wall side
                return speed * 0.7, s * 0.45
            self.had_wall = False
            return self.seek(view, speed, pose)
        self.lost_for = 0.0
        self.had_wall = True
        d = min(abs(y) for _, y in perp)
        alpha = 0.0
        if diag:
            (px, py), (qx, qy) = min(perp, key=lambda p: abs(p[1])), min(diag, key=lambda p: abs(p[1]))
            # direction of the wall line, forward along it; 0 when parallel to the robot
            alpha = math.atan2(qy - py, qx - px) if qx > px + 0.05 else 0.0
        error = d_set - d  # > 0: too close
        w = _clip(-s * kp * error + kd * alpha, -0.9, 0.9)
        return speed * _clip(1.0 - 0.5 * abs(w), 0.3, 1.0), w

    def seek(self, view: SonarView, speed: float,
             pose: tuple[float, float, float] | None) -> tuple[float, float]:
        """No wall near: head for the nearest point of the border rectangle, if one is known."""
        target = self._nearest_border_point(pose) if pose is not None else None
        if target is None:
            return speed, 0.0  # straight on until a wall shows up ahead
        x, y, th = pose
        err = math.atan2(target[1] - y, target[0] - x) - th
        err = math.atan2(math.sin(err), math.cos(err))
        return avoid(view, speed, 0.8, 0.8, self._avoid, bias=_clip(1.5 * err, -0.8, 0.8))

    def _on_border(self, point: tuple[float, float], pose) -> bool:
        """Is this echo (robot frame) on the border? Interior obstacles are not followed.

        Without odometry or a border rectangle every wall counts. The tolerance absorbs
        odometry drift over a few laps."""
        if pose is None:
            return True
        x, y, th = pose
        wx = x + point[0] * math.cos(th) - point[1] * math.sin(th)
        wy = y + point[0] * math.sin(th) + point[1] * math.cos(th)
        nearest = self._nearest_border_point((wx, wy, 0.0))
        return nearest is None or math.hypot(nearest[0] - wx, nearest[1] - wy) < 1.5

    def _nearest_border_point(self, pose) -> tuple[float, float] | None:
        try:
            x0, y0 = float(self.params["x_min"]), float(self.params["y_min"])
            x1, y1 = float(self.params["x_max"]), float(self.params["y_max"])
        except (KeyError, TypeError, ValueError):
            return None
        x, y = pose[0], pose[1]
        options = [(x0, _clip(y, y0, y1)), (x1, _clip(y, y0, y1)),
                   (_clip(x, x0, x1), y0), (_clip(x, x0, x1), y1)]
        return min(options, key=lambda p: math.hypot(p[0] - x, p[1] - y))


class ReportLayer(_SonarLayer):
    params_section = "Report"

    def __init__(self, ctx: AgentContext):
        super().__init__(ctx)
        self.ledger = PatrolLedger(ctx, ctx.layer_params.get("BorderProtection") or {})

    def on_activate(self, now: float) -> None:
        self.state: dict = {}
        self.sent = False

    def step(self, now: float, dt: float) -> None:
        view, pose = self.sonar(now), self.pose(now)
        if view is None or pose is None:
            self.ctx.publish_cmd(0.0, 0.0)
            return
        gx, gy = float(self.params.get("x", 0.0)), float(self.params.get("y", 0.0))
        x, y, th = pose
        dist = math.hypot(gx - x, gy - y)
        if dist < 0.5:
            self.ctx.publish_cmd(0.0, 0.0)
            if not self.sent:
                self.ctx.bus.publish(keys.patrol_report(self.ctx.robot_id),
                                     self.ledger.report(self.ctx.robot_id, now))
                self.ctx.log.info("%s: report published at (%.1f, %.1f)", self.ctx.robot_id, x, y)
                self.sent = True
            return
        err = math.atan2(gy - y, gx - x) - th
        err = math.atan2(math.sin(err), math.cos(err))
        speed = float(self.params.get("speed", 0.5)) * _clip(dist / 1.5, 0.3, 1.0)
        v, w = avoid(view, speed, 0.8, 0.8, self.state, bias=_clip(1.2 * err, -0.8, 0.8))
        if abs(err) > 1.2 and v > 0:
            v *= 0.3  # mostly turn first
        self.ctx.publish_cmd(v, w)


class PatrolLedger:
    """Team bookkeeping from the bus: time per robot and task, distance, border cells visited."""

    CELL = 0.5
    REACH = 2.0  # a border cell counts as visited when a robot passes within this distance

    def __init__(self, ctx: AgentContext, border: dict):
        self.ctx = ctx
        self._lock = threading.Lock()
        self.task_time: dict[tuple[str, str], float] = {}
        self._last_bc: dict[str, tuple[str, float]] = {}
        self._last_pos: dict[str, tuple[float, float]] = {}
        self.distance: dict[str, float] = {}
        try:
            x0, y0 = float(border.get("x_min")), float(border.get("y_min"))
            x1, y1 = float(border.get("x_max")), float(border.get("y_max"))
        except (TypeError, ValueError):
            x0 = y0 = x1 = y1 = None
        self.cells = rectangle_cells(x0, y0, x1, y1, self.CELL) if x0 is not None else []
        self.visited = [False] * len(self.cells)
        ctx.bus.subscribe(keys.ALL_INTER_ROBOT_COMMUNICATION, self._on_bc,
                          msg_type=InterRobotCommunication)
        ctx.bus.subscribe("*/odom", self._on_odom, msg_type=Odometry)

    def _on_bc(self, sample) -> None:
        msg = sample.message
        rid, now = msg.header.frame_id, self.ctx.clock.now()
        with self._lock:
            last = self._last_bc.get(rid)
            if last is not None and last[0] == msg.task_id and now - last[1] < 5.0:
                k = (rid, msg.task_id)
                self.task_time[k] = self.task_time.get(k, 0.0) + (now - last[1])
            self._last_bc[rid] = (msg.task_id, now)

    def _on_odom(self, sample) -> None:
        rid = keys.first_chunk(sample.key)
        p = sample.message.pose
        with self._lock:
            last = self._last_pos.get(rid)
            if last is not None:
                self.distance[rid] = self.distance.get(rid, 0.0) + math.hypot(p.x - last[0],
                                                                              p.y - last[1])
            self._last_pos[rid] = (p.x, p.y)
            for i, (cx, cy) in enumerate(self.cells):
                if not self.visited[i] and math.hypot(cx - p.x, cy - p.y) <= self.REACH:
                    self.visited[i] = True

    def report(self, reporter: str, now: float) -> Report:
        with self._lock:
            covered = sum(self.visited) / len(self.cells) if self.cells else 0.0
            times = tuple(TaskTime(r, t, s) for (r, t), s in sorted(self.task_time.items()))
            return Report(Header(reporter, now), sum(self.distance.values()), covered, times)


# ------------------------------------------------------------------------------ evaluators

class WallInRange(SensoryEvaluator):
    """Applicable while the sonar is fresh and some echo is within `range` metres (default 4)."""

    def __init__(self, task_id, sensors, ctx: AgentContext):
        super().__init__(task_id, sensors, ctx)
        self.range = float((ctx.layer_params.get("BorderProtection") or {}).get("wall_range", 4.0))

    def is_applicable(self, now: float) -> bool:
        for s in self.sensors:
            if not s.is_up_to_date(now):
                return False
            if isinstance(s.latest, PointCloud):
                view = SonarView(s.latest)
                if any(r <= self.range for _, _, r, _ in view.points):
                    return True
        return False


class ReportDue(SensoryEvaluator):
    """Applicable while sensors are fresh and no robot has reported for `Report/period` seconds."""

    def __init__(self, task_id, sensors, ctx: AgentContext):
        super().__init__(task_id, sensors, ctx)
        self.period = float((ctx.layer_params.get("Report") or {}).get("period", 60.0))
        self.last_report: float | None = None
        ctx.bus.subscribe("*/patrol/report", self._on_report, msg_type=Report)

    def _on_report(self, sample) -> None:
        self.last_report = self.ctx.clock.now()

    def is_applicable(self, now: float) -> bool:
        if not all(s.is_up_to_date(now) for s in self.sensors):
            return False
        return self.last_report is None or now - self.last_report >= self.period
