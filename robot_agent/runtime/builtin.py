"""The built-in plugins every architecture can use, registered as `mrta/odometry`,
`mrta/point_cloud` and `mrta/updated_sensory` (a task is applicable while all of its sensors are
up to date). They were ALLIANCE's, named `alliance/*`; those names stay aliases, so the
dissertation's files and every shipped parameter file load unchanged."""

from __future__ import annotations

from mrta_zenoh.messages import Odometry, PointCloud

from .plugins import Sensor, SensoryEvaluator


ALIASES = {"alliance/odometry": "mrta/odometry", "alliance/point_cloud": "mrta/point_cloud",
           "alliance/updated_sensory": "mrta/updated_sensory"}


class OdometrySensor(Sensor):
    message_type = Odometry


class PointCloudSensor(Sensor):
    message_type = PointCloud


class UpdatedSensory(SensoryEvaluator):
    def is_applicable(self, now: float) -> bool:
        return all(s.is_up_to_date(now) for s in self.sensors)
