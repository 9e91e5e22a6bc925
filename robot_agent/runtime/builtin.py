"""The built-in plugins every architecture can use, registered as `mrta/odometry`,
`mrta/point_cloud` and `mrta/updated_sensory` (a task is applicable while all of its sensors are
up to date). They were ALLIANCE's, named `alliance/*`; those names stay aliases, so the
dissertation's files and every shipped parameter file load unchanged."""

from __future__ import annotations

from mrta_zenoh.messages import Odometry, PointCloud

from .plugins import AgentContext, Sensor, SensoryEvaluator


ALIASES = {"alliance/odometry": "mrta/odometry", "alliance/point_cloud": "mrta/point_cloud",
           "alliance/updated_sensory": "mrta/updated_sensory"}


class OdometrySensor(Sensor):
    message_type = Odometry


def odometry_pose(ctx: AgentContext, now: float, topic: str = "odom"
                  ) -> tuple[float, float, float] | None:
    """The robot's pose (x, y, θ) from its odometry sensor `topic`, or None while that sensor
    is missing, stale or has heard no Odometry: what a layer steering by odometry reads."""
    s = ctx.sensors.get(topic)
    if s is None or not s.is_up_to_date(now) or not isinstance(s.latest, Odometry):
        return None
    p = s.latest.pose
    return p.x, p.y, p.theta


class PointCloudSensor(Sensor):
    message_type = PointCloud


class UpdatedSensory(SensoryEvaluator):
    def is_applicable(self, now: float) -> bool:
        return all(s.is_up_to_date(now) for s in self.sensors)
