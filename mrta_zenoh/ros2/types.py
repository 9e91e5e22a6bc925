"""ROS 2 message types through `rosbags`: CDR bytes, RIHS01 type hashes, and the conversions
between our messages and ROS 2's.

rosbags ships the message stores of every ROS 2 distro, serializes CDR (3–9× faster than pycdr2)
and computes REP-2011 type hashes, which match the published ones (tests/test_ros2_wire.py).
Humble predates type hashes: rmw_zenoh's Humble build writes `TypeHashNotSupported` instead.
Architectures add their own types through `mrta.ros2.mirrors` (their `.msg` definitions are
registered into the same store).

Conversions keep what both sides carry and say what they drop: our Odometry is planar (x, y,
θ ↔ position and a yaw quaternion; covariances zero), a ROS 2 Header has no sequence number
(ours counts per bridge), our sonar is points in the robot frame (PointCloud, PointCloud2 with
x y z float32 fields, or a LaserScan of one-degree bins).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

from ..errors import ConfigError
from ..messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist

DISTROS = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY,
           "kilted": Stores.ROS2_KILTED, "lyrical": Stores.ROS2_LYRICAL}
DEFAULT_DISTRO = "jazzy"
NO_HASH = "TypeHashNotSupported"
TWIST = "geometry_msgs/msg/Twist"
ODOMETRY = "nav_msgs/msg/Odometry"
SONAR_TYPES = {"pointcloud": "sensor_msgs/msg/PointCloud",
               "pointcloud2": "sensor_msgs/msg/PointCloud2",
               "laserscan": "sensor_msgs/msg/LaserScan"}
SCAN_BINS = 360  # a LaserScan made of our sonar points: one-degree bins, +inf where no echo
MAX_RANGE = 5.0  # metres: a Pioneer sonar's range, the LaserScan's range_max


class Ros2Types:
    """One distro's message store, plus the architectures' own definitions."""

    def __init__(self, distro: str = DEFAULT_DISTRO, extra: dict[str, str] | None = None):
        if distro not in DISTROS:
            raise ConfigError(f"ROS 2 distro {distro!r}: expected one of {', '.join(DISTROS)}")
        self.distro = distro
        self.store = get_typestore(DISTROS[distro])
        for name, text in (extra or {}).items():
            self.store.register(get_types_from_msg(text, name))
        self._hashes: dict[str, str] = {}

    def hash(self, ros_type: str) -> str:
        h = self._hashes.get(ros_type)
        if h is None:
            self.require(ros_type)
            h = NO_HASH if self.distro == "humble" else self.store.hash_rihs01(ros_type)
            self._hashes[ros_type] = h
        return h

    def require(self, ros_type: str) -> None:
        if ros_type not in self.store.types:
            raise ConfigError(f"ROS 2 type {ros_type!r} is not in the {self.distro} message store")

    def new(self, ros_type: str, **fields: Any) -> Any:
        return self.store.types[ros_type](**fields)

    def serialize(self, msg: Any, ros_type: str) -> bytes:
        return bytes(self.store.serialize_cdr(msg, ros_type))

    def deserialize(self, data: bytes, ros_type: str) -> Any:
        return self.store.deserialize_cdr(data, ros_type)

    # ------------------------------------------------------------------ pieces
    def time(self, stamp: float) -> Any:
        sec = math.floor(stamp)
        return self.new("builtin_interfaces/msg/Time", sec=int(sec),
                        nanosec=min(int(round((stamp - sec) * 1e9)), 999_999_999))

    def header(self, stamp: float, frame_id: str) -> Any:
        return self.new("std_msgs/msg/Header", stamp=self.time(stamp), frame_id=frame_id)

    def vector(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
        return self.new("geometry_msgs/msg/Vector3", x=x, y=y, z=z)

    # ------------------------------------------------------------------ ours → ROS 2
    def twist_to_ros(self, msg: Twist) -> Any:
        return self.new(TWIST, linear=self.vector(msg.linear), angular=self.vector(z=msg.angular))

    def odometry_to_ros(self, msg: Odometry, frame_id: str = "odom",
                        child_frame_id: str = "base_link") -> Any:
        p, t = msg.pose, msg.twist
        pose = self.new("geometry_msgs/msg/Pose",
                        position=self.new("geometry_msgs/msg/Point", x=p.x, y=p.y, z=0.0),
                        orientation=self.new("geometry_msgs/msg/Quaternion", x=0.0, y=0.0,
                                             z=math.sin(p.theta / 2), w=math.cos(p.theta / 2)))
        zeros = np.zeros(36, dtype=np.float64)
        return self.new(
            ODOMETRY, header=self.header(msg.header.stamp, frame_id),
            child_frame_id=child_frame_id,
            pose=self.new("geometry_msgs/msg/PoseWithCovariance", pose=pose, covariance=zeros),
            twist=self.new("geometry_msgs/msg/TwistWithCovariance",
                           twist=self.twist_to_ros(t), covariance=zeros.copy()))

    def sonar_to_ros(self, msg: PointCloud, kind: str, frame_id: str = "sonar") -> Any:
        header = self.header(msg.header.stamp, frame_id)
        pts = msg.points
        if kind == "pointcloud":
            return self.new(SONAR_TYPES[kind], header=header, channels=[], points=[
                self.new("geometry_msgs/msg/Point32", x=float(np.float32(p.x)),
                         y=float(np.float32(p.y)), z=0.0) for p in pts])
        if kind == "pointcloud2":
            xyz = np.zeros((len(pts), 3), dtype="<f4")
            for i, p in enumerate(pts):
                xyz[i, 0], xyz[i, 1] = p.x, p.y
            fields = [self.new("sensor_msgs/msg/PointField", name=n, offset=4 * i, datatype=7,
                               count=1) for i, n in enumerate("xyz")]
            return self.new(SONAR_TYPES[kind], header=header, height=1, width=len(pts),
                            fields=fields, is_bigendian=False, point_step=12,
                            row_step=12 * len(pts), data=xyz.reshape(-1).view(np.uint8),
                            is_dense=True)
        ranges = np.full(SCAN_BINS, np.inf, dtype=np.float32)
        step = 2 * math.pi / SCAN_BINS
        for p in pts:
            i = int(round((math.atan2(p.y, p.x) + math.pi) / step)) % SCAN_BINS
            ranges[i] = min(ranges[i], math.hypot(p.x, p.y))
        return self.new(SONAR_TYPES["laserscan"], header=header, angle_min=-math.pi,
                        angle_max=math.pi - step, angle_increment=step, time_increment=0.0,
                        scan_time=0.0, range_min=0.0, range_max=MAX_RANGE, ranges=ranges,
                        intensities=np.zeros(0, dtype=np.float32))

    # ------------------------------------------------------------------ ROS 2 → ours
    @staticmethod
    def stamp(header: Any) -> float:
        return header.stamp.sec + header.stamp.nanosec * 1e-9

    def twist_from_ros(self, msg: Any) -> Twist:
        return Twist(float(msg.linear.x), float(msg.angular.z))

    def odometry_from_ros(self, msg: Any, frame_id: str, seq: int) -> Odometry:
        q = msg.pose.pose.orientation
        theta = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
        pos = msg.pose.pose.position
        return Odometry(Header(frame_id, self.stamp(msg.header), seq),
                        Pose2D(float(pos.x), float(pos.y), theta),
                        self.twist_from_ros(msg.twist.twist))

    def sonar_from_ros(self, msg: Any, kind: str, frame_id: str, seq: int) -> PointCloud:
        header = Header(frame_id, self.stamp(msg.header), seq)
        if kind == "pointcloud":
            pts = [(float(p.x), float(p.y)) for p in msg.points]
        elif kind == "pointcloud2":
            pts = _xy_from_cloud2(msg)
        else:
            r = np.asarray(msg.ranges, dtype=np.float64)
            a = msg.angle_min + msg.angle_increment * np.arange(len(r))
            ok = np.isfinite(r) & (r >= msg.range_min) & (r <= msg.range_max)
            pts = list(zip((r[ok] * np.cos(a[ok])).tolist(), (r[ok] * np.sin(a[ok])).tolist()))
        return PointCloud(header, tuple(Point2D(x, y) for x, y in pts
                                        if math.isfinite(x) and math.isfinite(y)))


def _xy_from_cloud2(msg: Any) -> list[tuple[float, float]]:
    """x and y of every point of a PointCloud2 (float32 or float64 fields, either byte order)."""
    offsets = {f.name: (f.offset, f.datatype) for f in msg.fields}
    if "x" not in offsets or "y" not in offsets:
        raise ValueError("PointCloud2 without x and y fields")
    kinds = {7: "f4", 8: "f8"}
    order = ">" if msg.is_bigendian else "<"
    data = np.asarray(msg.data, dtype=np.uint8).tobytes()
    n = msg.width * msg.height
    if msg.point_step <= 0 or len(data) < n * msg.point_step:
        raise ValueError("PointCloud2 data shorter than width × height × point_step")
    out = []
    for axis in ("x", "y"):
        off, dt = offsets[axis]
        if dt not in kinds:
            raise ValueError(f"PointCloud2 field {axis} has datatype {dt}; expected float32/64")
        out.append(np.ndarray((n,), dtype=order + kinds[dt], buffer=data, offset=off,
                              strides=(msg.point_step,)).astype(np.float64))
    return list(zip(out[0].tolist(), out[1].tolist()))
