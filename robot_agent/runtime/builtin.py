"""ALLIANCE's built-in plugins, registered as `alliance/odometry`, `alliance/point_cloud` and
`alliance/updated_sensory` (a behaviour is applicable while all of its sensors are up to date)."""

from __future__ import annotations

from mrta_zenoh.messages import Odometry, PointCloud

from .plugins import Sensor, SensoryEvaluator


class OdometrySensor(Sensor):
    message_type = Odometry


class PointCloudSensor(Sensor):
    message_type = PointCloud


class UpdatedSensory(SensoryEvaluator):
    def is_applicable(self, now: float) -> bool:
        return all(s.is_up_to_date(now) for s in self.sensors)
