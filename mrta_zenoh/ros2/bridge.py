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

Limits (issue #23; docs/ros2.md, "Limits"), so one ROS 2 publisher cannot take the bridge down:

* a sample larger than its cap is dropped before it is decoded (`oversized` in the
  subscription's counts): odometry 16 KiB (a real one is 724 bytes), sonar 64 KiB by default
  (`--max-sonar-bytes`; a PointCloud of ≈ 5,400 points, 5 ms to convert). Before, a 1M-point
  cloud twice a second held a core at 100 % and grew the bridge from 58 to 409 MB;
* a message is checked as every receiver on our bus will check it (the strict codec: finite
  floats, field types) before it is published: NaN odometry used to be forwarded and then
  dropped by every receiver; now it is dropped here, once, and counted (`non-finite`);
* `--mirror` publishes only the bridged robots' own keys and at most MAX_MIRRORED ROS 2 topics
  per robot; when full, a new key takes the place of one silent for MIRROR_IDLE seconds, or is
  dropped and counted (`mirror limit`). Before, 2,920 invented keys made 2,923 topics.
"""

from __future__ import annotations

import logging
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

from .. import codec
from ..bus import BusOptions
from ..errors import ConfigError
from ..keys import ROS2_BRIDGE_TOKEN, cmd_vel, normalize_robot_id, odom, sonar, validate_key_expr
from ..identity import BRIDGE, bridge_node_name
from ..lifecycle import wait_for_stop
from ..messages import Message, Twist
from ..node import Node
from ..yamlfile import plural
from . import names
from .mirror import Mirror, definitions, registered_mirrors
from .names import COMMANDS, SENSOR_DATA
from .node import Ros2Node
from .types import ODOMETRY, SONAR_TYPES, TWIST, Ros2Types

log = logging.getLogger("mrta.ros2")

ODOM_MAX_BYTES = 16 * 1024    # a nav_msgs/Odometry is 724 bytes with short frame ids
SONAR_MAX_BYTES = 64 * 1024   # default of --max-sonar-bytes: ≈ 5,400 PointCloud points
MAX_MIRRORED = 64             # mirrored ROS 2 topics per robot (patrol: 3 tasks → 4)
MIRROR_IDLE = 10.0            # seconds: a mirrored topic this silent may give its place up


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
                 mirror: bool = False, max_sonar_bytes: int = SONAR_MAX_BYTES,
                 max_mirrored: int = MAX_MIRRORED,
                 monotonic: Callable[[], float] = time.monotonic):
        if max_sonar_bytes < 1 or max_mirrored < 1:
            raise ConfigError("the sonar size cap and the mirrored topic cap must be ≥ 1")
        self.bus = bus
        self.mirrors: list[Mirror] = registered_mirrors() if mirror else []
        self.types = Ros2Types(distro, definitions(self.mirrors))
        self.stats = BridgeStats()
        self.max_sonar_bytes, self.max_mirrored = max_sonar_bytes, max_mirrored
        self._monotonic = monotonic
        self._lock = threading.Lock()
        self._seq: dict[str, int] = {}
        self._mirrored: dict[str, dict[str, list]] = {}  # robot → key → [publisher, last used]
        self._closing: list = []
        name = bridge_node_name([link.robot for link in links])
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
            self._forward(odom_key, ours)

        def on_sonar(msg, att) -> None:
            try:
                ours = types.sonar_from_ros(msg, link.sonar_type, f"{link.robot}/sonar",
                                            self._next(sonar_key))
            except (ValueError, TypeError, AttributeError) as exc:
                self._dropped(sonar_key, exc)
                return
            self._forward(sonar_key, ours)

        node.subscription(names.resolve(ns, link.odom), ODOMETRY, SENSOR_DATA, on_odom,
                          max_payload=ODOM_MAX_BYTES)
        node.subscription(names.resolve(ns, link.sonar), SONAR_TYPES[link.sonar_type],
                          SENSOR_DATA, on_sonar, max_payload=self.max_sonar_bytes)
        for m in self.mirrors:
            self._mirror(link, m)
        self._closing.append(self.bus.declare_token(f"{ROS2_BRIDGE_TOKEN}/{link.robot}"))
        log.info("bridging %s ↔ ROS 2 %s (cmd_vel, odom, sonar as %s%s)", link.robot, ns,
                 link.sonar_type, f", {plural(len(self.mirrors), 'mirror')}" if self.mirrors else "")

    def _forward(self, key: str, ours: Message) -> None:
        """Publish a converted ROS 2 message on our bus — if every receiver would accept it:
        the strict codec checks it here (a NaN pose from a ROS 2 driver is dropped once, here,
        counted, instead of being sent to every receiver to drop)."""
        payload = codec.encode(ours)
        try:
            codec.decode(ours.TYPE_NAME, payload)
        except codec.DecodeError as exc:
            self._dropped(key, exc, "non-finite" if isinstance(exc, codec.NonFinite)
                          else "invalid")
            return
        self.bus.publish_raw(key, codec.encoding_for(ours.TYPE_NAME), payload, lossy=True)
        self.stats.add(self.stats.from_ros, key)

    def _mirror(self, link: RobotLink, m: Mirror) -> None:
        """robotN/<suffix> → the ROS 2 topic <ns>/<rest of the key>, one publisher per key, at
        most `max_mirrored` per robot (shared by the robot's mirrors). Drops are counted under
        the key expression, not the key: invented keys must not grow the counters either."""
        pubs = self._mirrored.setdefault(link.robot, {})
        cut = len(link.robot) + 1
        key_expr = validate_key_expr(f"{link.robot}/{m.suffix}")

        def on_sample(sample) -> None:
            try:
                pub = self._mirror_publisher(pubs, link.namespace, m, sample.key,
                                             sample.key[cut:])
            except ConfigError as exc:  # the rest of the key is not a ROS name
                self._dropped(key_expr, exc, "not a ROS name")
                return
            if pub is None:
                self._dropped(key_expr, ValueError(
                    f"{sample.key}: {self.max_mirrored} mirrored topics of {link.robot} are "
                    f"active"), "mirror limit")
                return
            try:
                pub.publish(m.convert(self.types, sample.message))
            except (ValueError, TypeError) as exc:
                self._dropped(key_expr, exc)
                return
            self.stats.add(self.stats.to_ros, pub.topic)

        self._closing.append(self.bus.subscribe(key_expr, on_sample, msg_type=m.our_type))

    def _mirror_publisher(self, pubs: dict, namespace: str, m: Mirror, key: str, rest: str):
        """The publisher of `key` (made on first use); None if the robot's mirrored topics are
        all taken and none has been silent MIRROR_IDLE seconds — then the one silent longest
        gives its place up (its token goes, so ROS 2 tools stop listing it)."""
        now = self._monotonic()
        with self._lock:
            entry = pubs.get(key)
            if entry is not None:
                entry[1] = now
                return entry[0]
            topic = names.resolve(namespace, rest)
            if len(pubs) >= self.max_mirrored:
                oldest = min(pubs, key=lambda k: pubs[k][1])
                if now - pubs[oldest][1] < MIRROR_IDLE:
                    return None
                self.node.remove(pubs.pop(oldest)[0])
                log.info("mirror: %s (silent) gives its ROS 2 topic up to %s", oldest, key)
            pub = self.node.publisher(topic, m.ros_type, m.qos)
            pubs[key] = [pub, now]
            return pub

    def _next(self, key: str) -> int:
        with self._lock:
            n = self._seq[key] = self._seq.get(key, 0) + 1
        return n

    def _dropped(self, what: str, exc: Exception, reason: str = "") -> None:
        """Count a dropped message under `what` (a key), or `what (reason)`; warn once each."""
        name = f"{what} ({reason})" if reason else what
        with self._lock:
            n = self.stats.dropped[name] = self.stats.dropped.get(name, 0) + 1
        if n == 1:
            log.warning("dropping %s: %s (counted)", name, exc)

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
               max_sonar_bytes: int = SONAR_MAX_BYTES,
               stop: threading.Event | None = None) -> BridgeStats:
    """Bridge until stopped. In a secured fleet, refuse to start with a certificate that is not
    a bridge's for these robots: the router would drop all it says without a word."""
    if not links:
        raise ConfigError("give at least one --robot")
    robots = [link.robot for link in links]
    if len(set(robots)) != len(robots):
        raise ConfigError("a robot is given twice")
    with Node(bus_options, BRIDGE, robots=robots, stop=stop) as node, \
            Bridge(node.bus, links, domain=domain, distro=distro, mirror=mirror,
                   max_sonar_bytes=max_sonar_bytes) as bridge:
        log.info("ready: ROS 2 domain %d (%s), %s", domain, distro, ", ".join(robots))
        wait_for_stop(node.stop)  # in slices: a signal taken by a Zenoh thread is still seen
        counts = bridge.subscription_counts()
    log.info("done: to ROS 2 %s; from ROS 2 %s; dropped %s; subscriptions %s",
             bridge.stats.to_ros, bridge.stats.from_ros, bridge.stats.dropped, counts)
    return bridge.stats
