"""`mrta ros2 bridge`: a ROS 2 robot's topics ↔ our keys, over rmw_zenoh.

For each robot (one process per robot or per fleet):

    robotN/cmd_vel (Twist)   → geometry_msgs/msg/Twist on <ns>/cmd_vel   reliable, depth 10
    <ns>/odom  nav_msgs/msg/Odometry                 → robotN/odom        best effort accepted
    <ns>/sonar PointCloud | PointCloud2 | LaserScan  → robotN/sonar

with a node `/mrta_bridge_<robot>` (outside the robot's namespace: the robot's namespace holds
the robot's own nodes, which is how the supervisor tells a driver from us) whose publisher and
subscription tokens make `ros2 node list` / `ros2 topic list` show it. With `mirror`, every
message an architecture registers under `mrta.ros2.mirrors` (ALLIANCE: InterRobotCommunication,
Motivation) is also published on the ROS 2 topic named like its key.

Attachments are strict both ways (mrta_zenoh.ros2.attachment); a sample that cannot be decoded
or converted is counted and dropped. The bridge holds `@mrta/ros2_bridge/<robot>` while it runs
— never a `robotN/**` token, so a bridge alone never makes a robot look online.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

from ..bus import BusOptions, open_bus
from ..errors import ConfigError
from ..keys import ROS2_BRIDGE_TOKEN, cmd_vel, normalize_robot_id, odom, sonar, validate_key_expr
from ..lifecycle import stop_on_signals
from ..messages import Twist
from . import names
from .mirror import Mirror, definitions, registered_mirrors
from .names import COMMANDS, SENSOR_DATA
from .node import Ros2Node
from .types import ODOMETRY, SONAR_TYPES, TWIST, Ros2Types

log = logging.getLogger("mrta.ros2")


@dataclass(frozen=True)
class RobotLink:
    """One robot's side of the bridge: its id on our bus and its ROS 2 names."""

    robot: str
    namespace: str
    cmd_vel: str = "cmd_vel"
    odom: str = "odom"
    sonar: str = "sonar"
    sonar_type: str = "pointcloud"

    @classmethod
    def make(cls, robot: str, namespace: str | None = None, **names_: str) -> "RobotLink":
        rid = normalize_robot_id(robot)
        link = cls(rid, names.normalize_namespace(namespace if namespace is not None
                                                  else "/" + rid), **names_)
        if link.sonar_type not in SONAR_TYPES:
            raise ConfigError(f"--sonar-type {link.sonar_type!r}: expected one of "
                              f"{', '.join(SONAR_TYPES)}")
        for topic in (link.cmd_vel, link.odom, link.sonar):
            names.resolve(link.namespace, topic)
        return link


@dataclass
class BridgeStats:
    to_ros: dict[str, int] = field(default_factory=dict)
    from_ros: dict[str, int] = field(default_factory=dict)
    dropped: dict[str, int] = field(default_factory=dict)

    def add(self, table: dict[str, int], key: str) -> None:
        table[key] = table.get(key, 0) + 1


class Bridge:
    """The mapping for a set of robots, on an open ZenohBus; close() undeclares everything."""

    def __init__(self, bus, links: list[RobotLink], *, domain: int = 0, distro: str = "jazzy",
                 mirror: bool = False):
        self.bus = bus
        self.mirrors: list[Mirror] = registered_mirrors() if mirror else []
        self.types = Ros2Types(distro, definitions(self.mirrors))
        self.stats = BridgeStats()
        self._lock = threading.Lock()
        self._seq: dict[str, int] = {}
        self._closing: list = []
        name = f"mrta_bridge_{links[0].robot}" if len(links) == 1 else "mrta_bridge"
        self.node = Ros2Node(bus, self.types, name=name, namespace="/", domain=domain)
        for link in links:
            self._link(link)

    def _link(self, link: RobotLink) -> None:
        types, node, stats = self.types, self.node, self.stats
        ns = link.namespace
        cmd = node.publisher(names.resolve(ns, link.cmd_vel), TWIST, COMMANDS)

        def on_cmd(sample) -> None:
            try:
                cmd.publish(types.twist_to_ros(sample.message))
            except (ValueError, TypeError) as exc:
                self._dropped("cmd_vel", exc)
                return
            stats.add(stats.to_ros, cmd.topic)

        self._closing.append(self.bus.subscribe(cmd_vel(link.robot), on_cmd, msg_type=Twist))

        odom_key, sonar_key = odom(link.robot), sonar(link.robot)

        def on_odom(msg, att) -> None:
            try:
                ours = types.odometry_from_ros(msg, f"{link.robot}/odom", self._next(odom_key))
            except (ValueError, TypeError, AttributeError) as exc:
                self._dropped(odom_key, exc)
                return
            self.bus.publish(odom_key, ours, lossy=True)
            stats.add(stats.from_ros, odom_key)

        def on_sonar(msg, att) -> None:
            try:
                ours = types.sonar_from_ros(msg, link.sonar_type, f"{link.robot}/sonar",
                                            self._next(sonar_key))
            except (ValueError, TypeError, AttributeError) as exc:
                self._dropped(sonar_key, exc)
                return
            self.bus.publish(sonar_key, ours, lossy=True)
            stats.add(stats.from_ros, sonar_key)

        node.subscription(names.resolve(ns, link.odom), ODOMETRY, SENSOR_DATA, on_odom)
        node.subscription(names.resolve(ns, link.sonar), SONAR_TYPES[link.sonar_type],
                          SENSOR_DATA, on_sonar)
        for m in self.mirrors:
            self._mirror(link, m)
        self._closing.append(self.bus.declare_token(f"{ROS2_BRIDGE_TOKEN}/{link.robot}"))
        log.info("bridging %s ↔ ROS 2 %s (cmd_vel, odom, sonar as %s%s)", link.robot, ns,
                 link.sonar_type, f", {len(self.mirrors)} mirrors" if self.mirrors else "")

    def _mirror(self, link: RobotLink, m: Mirror) -> None:
        """robotN/<suffix> → the ROS 2 topic <ns>/<rest of the key>, one publisher per key."""
        pubs: dict[str, object] = {}
        cut = len(link.robot) + 1

        def on_sample(sample) -> None:
            pub = pubs.get(sample.key)
            if pub is None:
                try:
                    topic = names.resolve(link.namespace, sample.key[cut:])
                except ConfigError as exc:
                    self._dropped(sample.key, exc)
                    return
                pub = pubs[sample.key] = self.node.publisher(topic, m.ros_type, m.qos)
            try:
                pub.publish(m.convert(self.types, sample.message))
            except (ValueError, TypeError) as exc:
                self._dropped(sample.key, exc)
                return
            self.stats.add(self.stats.to_ros, pub.topic)

        key_expr = validate_key_expr(f"{link.robot}/{m.suffix}")
        self._closing.append(self.bus.subscribe(key_expr, on_sample, msg_type=m.our_type))

    def _next(self, key: str) -> int:
        with self._lock:
            n = self._seq[key] = self._seq.get(key, 0) + 1
        return n

    def _dropped(self, what: str, exc: Exception) -> None:
        with self._lock:
            n = self.stats.dropped[what] = self.stats.dropped.get(what, 0) + 1
        if n == 1:
            log.warning("dropping %s: %s", what, exc)

    def subscription_counts(self) -> dict[str, dict[str, int]]:
        return {s.topic: dict(s.counts) for s in self.node.subscriptions()}

    def close(self) -> None:
        for h in self._closing:
            h.close()
        self._closing.clear()
        self.node.close()

    def __enter__(self) -> "Bridge":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_bridge(*, links: list[RobotLink], bus_options: BusOptions, domain: int = 0,
               distro: str = "jazzy", mirror: bool = False,
               stop: threading.Event | None = None) -> BridgeStats:
    if not links:
        raise ConfigError("give at least one --robot")
    robots = [link.robot for link in links]
    if len(set(robots)) != len(robots):
        raise ConfigError("a robot is given twice")
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus, \
            Bridge(bus, links, domain=domain, distro=distro, mirror=mirror) as bridge:
        log.info("ready: ROS 2 domain %d (%s), %s", domain, distro, ", ".join(robots))
        stop.wait()
        counts = bridge.subscription_counts()
    log.info("done: to ROS 2 %s; from ROS 2 %s; dropped %s; subscriptions %s",
             bridge.stats.to_ros, bridge.stats.from_ros, bridge.stats.dropped, counts)
    return bridge.stats
