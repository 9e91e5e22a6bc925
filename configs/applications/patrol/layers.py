"""The patrol application's layers (dissertation §4.2): wander, border protection, report.

All three read the sonar as the simulator (or RosAria) publishes it: points in the robot frame,
metres; a point at the maximum range means "no echo". They never see the world map: a layer
knows only what its sensors tell it, as on the real robot.

* `patrol/wander`: keeps moving through open space; slows down as the way ahead closes, turns
  towards the more open side, and turns in place (committing to one direction) when blocked.
* `patrol/border_protection`: a PD wall follower on the side and diagonal sonars — distance
  error from the perpendicular beam, heading error from the line through the perpendicular and
  diagonal echoes — that turns at inner corners and curves back to a wall it lost at outer ones,
  so it goes round the whole perimeter (the original was stubbed to spin in place).
* `patrol/report`: drives to the report point, then publishes a team report on
  `robotN/patrol/report`. The report comes from the robot's ledger (ledger.py), which runs
  whether or not the behaviour is active: it logs the robot's own work and publishes that log
  on `robotN/patrol/log` once per `Report/log_period`; a report merges it with the latest log
  of each teammate.

Parameters are typed (msgspec Structs below): the agent checks the layers file against them when
it loads, so `speed: fast` is an error naming file and line before anything runs.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import msgspec

from mrta_zenoh.messages import PointCloud
from mrta_agent.runtime.builtin import odometry_pose
from mrta_agent.runtime.plugins import AgentContext, Layer

from .keys import report_key
from .ledger import PatrolLedger

NO_ECHO = 4.85  # m from the robot centre: beyond this a point is the sensor's "no echo"


# Sane ranges for the layers' parameters (finite is not enough: a speed of 1e308 is finite); a
# value outside is refused with its file, line and range.
Speed = Annotated[float, msgspec.Meta(gt=0.0, le=10.0, description="m/s")]
Distance = Annotated[float, msgspec.Meta(gt=0.0, le=100.0, description="m")]
TurnRate = Annotated[float, msgspec.Meta(gt=0.0, le=20.0, description="rad/s")]
Gain = Annotated[float, msgspec.Meta(ge=0.0, le=1000.0)]
Coordinate = Annotated[float, msgspec.Meta(ge=-10_000.0, le=10_000.0, description="m")]
Period = Annotated[float, msgspec.Meta(ge=0.001, le=86_400.0, description="s")]
# How often a robot publishes its own log (ledger.py): not below the odometry's 10 Hz, which
# drives it (a shorter period would change nothing but the check), and at most a minute, the
# report period, so a teammate's part of a report is never more than one report old.
LogPeriod = Annotated[float, msgspec.Meta(ge=0.1, le=60.0, description="s")]


class WanderParams(msgspec.Struct, forbid_unknown_fields=True):
    speed: Speed = 0.5
    safe_distance: Distance = 0.8
    turn_rate: TurnRate = 0.8


class BorderParams(msgspec.Struct, forbid_unknown_fields=True):
    """BorderProtection: the wall follower's gains, and the border rectangle (world metres)."""

    distance: Distance = 1.0
    speed: Speed = 0.4
    side: Literal["right", "left"] = "right"
    kp: Gain = 1.5
    kd: Gain = 2.0
    wall_range: Distance = 4.0
    x_min: Coordinate | None = None
    y_min: Coordinate | None = None
    x_max: Coordinate | None = None
    y_max: Coordinate | None = None

    def border(self) -> tuple[float, float, float, float] | None:
        corners = (self.x_min, self.y_min, self.x_max, self.y_max)
        return None if any(c is None for c in corners) else corners


class ReportParams(msgspec.Struct, forbid_unknown_fields=True):
    x: Coordinate = 0.0
    y: Coordinate = 0.0
    speed: Speed = 0.5
    period: Period = 60.0
    # the robot's own log goes to its teammates this often: a teammate's part of a report is
    # up to this old, and the team's ledger traffic is N² logs per log_period
    log_period: LogPeriod = 1.0


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
        return odometry_pose(self.ctx, now)


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
    Params = WanderParams
    draws = True  # its drift (the stream is made at setup: Plugin.draws)

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
        p = self.params
        v, w = avoid(view, p.speed, p.safe_distance, p.turn_rate, self.state, bias=self.drift)
        self.ctx.publish_cmd(v, w)


class BorderProtection(_SonarLayer):
    params_section = "BorderProtection"
    Params = BorderParams

    def on_activate(self, now: float) -> None:
        self.side = -1.0 if self.params.side == "right" else 1.0
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
        p = self.params
        d_set, speed, kp, kd = p.distance, p.speed, p.kp, p.kd
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
        border = self.params.border()
        if border is None:
            return None
        x0, y0, x1, y1 = border
        x, y = pose[0], pose[1]
        options = [(x0, _clip(y, y0, y1)), (x1, _clip(y, y0, y1)),
                   (_clip(x, x0, x1), y0), (_clip(x, x0, x1), y1)]
        return min(options, key=lambda p: math.hypot(p[0] - x, p[1] - y))


class ReportLayer(_SonarLayer):
    params_section = "Report"
    Params = ReportParams
    sections = {"BorderProtection": BorderParams}  # the ledger counts border cells

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        # the ledger logs this robot's work and publishes it from now on, active or not
        self.ledger = PatrolLedger(self, ctx.section("BorderProtection", BorderParams).border(),
                                   self.params.log_period)

    def on_activate(self, now: float) -> None:
        self.state: dict = {}
        self.sent = False

    def step(self, now: float, dt: float) -> None:
        view, pose = self.sonar(now), self.pose(now)
        if view is None or pose is None:
            self.ctx.publish_cmd(0.0, 0.0)
            return
        gx, gy = self.params.x, self.params.y
        x, y, th = pose
        dist = math.hypot(gx - x, gy - y)
        if dist < 0.5:
            self.ctx.publish_cmd(0.0, 0.0)
            if not self.sent:
                self.ctx.bus.publish(report_key(self.ctx.robot_id),
                                     self.ledger.report(self.ctx.robot_id, now))
                self.ctx.log.info("%s: report published at (%.1f, %.1f)", self.ctx.robot_id, x, y)
                self.sent = True
            return
        err = math.atan2(gy - y, gx - x) - th
        err = math.atan2(math.sin(err), math.cos(err))
        speed = self.params.speed * _clip(dist / 1.5, 0.3, 1.0)
        v, w = avoid(view, speed, 0.8, 0.8, self.state, bias=_clip(1.2 * err, -0.8, 0.8))
        if abs(err) > 1.2 and v > 0:
            v *= 0.3  # mostly turn first
        self.ctx.publish_cmd(v, w)


# The reference application (alliance_test) named these plugins; its files load unchanged.
ALIASES = {
    "alliance_test/odometry": "mrta/odometry",
    "alliance_test/point_cloud": "mrta/point_cloud",
    "alliance_test/updated_sensory": "mrta/updated_sensory",
    "alliance_test/wall_in_range": "patrol/wall_in_range",
    "alliance_test/report_due": "patrol/report_due",
    "alliance_test/wander": "patrol/wander",
    "alliance_test/border_protection": "patrol/border_protection",
    "alliance_test/report": "patrol/report",
}
