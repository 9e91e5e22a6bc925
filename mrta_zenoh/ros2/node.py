"""A ROS 2 node on a ZenohBus, as rmw_zenoh would make it: a node token, and per publisher or
subscription its own token, its data key and — for publishers — an attachment on every sample.

QoS as rmw_zenoh's `rmw_publisher_data.cpp` sets it: Zenoh's BLOCK congestion control only for
RELIABLE + KEEP_ALL, DROP for everything else — reliable KEEP_LAST too (with BLOCK a stalled
robot link could hold the bridge up). The GID in every attachment is the one rmw_zenoh
derives from the publisher's liveliness token (names.gid_of), so `ros2 topic info -v` and the
samples agree.

Durability and recovery as rmw_zenoh does them, through zenoh-ext's AdvancedPublisher and
AdvancedSubscriber (`rmw_publisher_data.cpp`, `rmw_subscription_data.cpp`, rmw_zenoh ≥ 0.2.2):

* a TRANSIENT_LOCAL publisher keeps its last `depth` samples in a cache, announces itself
  (publisher detection) and sends a heartbeat every 0.5 s, so a late ROS 2 subscriber gets the
  last sample(s) and a lost last sample is recovered;
* a TRANSIENT_LOCAL subscription asks for that history (at most `depth` samples) and detects
  late publishers; a RELIABLE one recovers missed samples from heartbeats.

Entities needing none of this (volatile publishers, best-effort volatile subscriptions: all of
the bridge's own) stay plain Zenoh ones, as before — same wire, same cost. Subscriptions are
strict like rmw_zenoh's: a sample without a valid 33-byte attachment, or whose CDR does not
decode, is counted and dropped, never passed on. A subscription may cap the payload size: a
larger sample is counted (`oversized`) and dropped before it is decoded — decoding is what
costs (a 1M-point cloud twice a second held a core at 100 % and grew the bridge by 350 MB),
and it runs on Zenoh's thread, where it would delay every other topic (docs/zenoh.md, trap 3).
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from typing import Any, Callable

from ..bus.zenoh_bus import AttachedPublisher, Closable, ZenohBus
from ..lifecycle import Closing
from . import names
from .attachment import Attachment, AttachmentError, Stamper
from .names import KEEP_ALL, RELIABLE, TRANSIENT_LOCAL, Qos
from .types import Ros2Types

log = logging.getLogger("mrta.ros2")
_ids = itertools.count(1)  # node and entity ids, unique in this process (as rmw_zenoh's)


HEARTBEAT = 0.5  # seconds: rmw_zenoh's heartbeat period for TRANSIENT_LOCAL publishers


def _advanced_publisher(bus: ZenohBus, key: str, qos: Qos) -> AttachedPublisher:
    """An AdvancedPublisher with a cache of `depth` samples, publisher detection and a periodic
    heartbeat; undeclared with the bus like the plain one."""
    from zenoh import ext

    return bus.declare_attached_publisher(
        key, lossy=not blocks(qos), declare=lambda k, **kw: ext.declare_advanced_publisher(
            bus.session, k, cache=ext.CacheConfig(max(1, qos.depth)), publisher_detection=True,
            sample_miss_detection=ext.MissDetectionConfig(heartbeat=HEARTBEAT), **kw))


def _advanced_subscription(bus: ZenohBus, key: str, qos: Qos,
                           handler: Callable[[str, bytes, bytes | None], None]) -> Closable:
    """An AdvancedSubscriber: history with late-publisher detection for TRANSIENT_LOCAL,
    recovery by heartbeat for RELIABLE. Errors in `handler` are counted as the bus counts them
    for plain subscriptions (`handler_errors`), never raised on Zenoh's thread."""
    from zenoh import ext

    history = (ext.HistoryConfig(detect_late_publishers=True, max_samples=max(1, qos.depth))
               if qos.durability == TRANSIENT_LOCAL else None)
    recovery = (ext.RecoveryConfig(periodic_queries=None, heartbeat=True)
                if qos.reliability == RELIABLE else None)
    return bus.subscribe_attached(key, handler, declare=lambda k, on_sample: (
        ext.declare_advanced_subscriber(bus.session, k, on_sample, history=history,
                                        recovery=recovery, subscriber_detection=True)))


def blocks(qos: Qos) -> bool:
    """Whether a publisher with this QoS uses BLOCK (rmw_zenoh: RELIABLE + KEEP_ALL only)."""
    return qos.reliability == RELIABLE and qos.history == KEEP_ALL


class Ros2Publisher:
    def __init__(self, node: "Ros2Node", topic: str, ros_type: str, qos: Qos):
        self.topic, self.ros_type, self.qos = topic, ros_type, qos
        types = node.types
        self.type_hash = types.hash(ros_type)
        self.key = names.topic_key(node.domain, topic, ros_type, self.type_hash)
        self.eid = next(_ids)
        token = names.endpoint_token(
            node.domain, node.zid, node.nid, self.eid, "MP", node.namespace, node.name, topic,
            ros_type, self.type_hash, qos, node.enclave)
        self.gid = names.gid_of(token)
        self.stamper = Stamper(self.gid)
        self._types = types
        if qos.durability == TRANSIENT_LOCAL:
            self._pub = _advanced_publisher(node.bus, self.key, qos)
        else:
            self._pub = node.bus.declare_attached_publisher(self.key, lossy=not blocks(qos))
        self._token = node.bus.declare_absolute_token(token)
        self.published = 0

    def publish(self, msg: Any) -> None:
        self.publish_cdr(self._types.serialize(msg, self.ros_type))

    def publish_cdr(self, payload: bytes) -> None:
        self._pub.put(payload, self.stamper.next(time.time_ns()))
        self.published += 1

    def close(self) -> None:
        self._token.close()
        self._pub.close()


class Ros2Subscription:
    def __init__(self, node: "Ros2Node", topic: str, ros_type: str, qos: Qos,
                 callback: Callable[[Any, Attachment], None], max_payload: int | None = None):
        self.topic, self.ros_type, self.qos = topic, ros_type, qos
        self.type_hash = node.types.hash(ros_type)
        self.key = names.topic_key(node.domain, topic, ros_type, self.type_hash)
        self.eid = next(_ids)
        self.max_payload = max_payload
        self.counts = {"received": 0, "no_attachment": 0, "bad_attachment": 0, "malformed": 0,
                       "oversized": 0}
        self._warned: set[str] = set()
        self._lock = threading.Lock()
        types = node.types

        def on_sample(key: str, payload: bytes, attachment: bytes | None) -> None:
            if max_payload is not None and len(payload) > max_payload:
                self._drop("oversized", key, ValueError(
                    f"{len(payload):,} bytes, more than the {max_payload:,} allowed"))
                return
            try:
                att = Attachment.unpack(attachment)
            except AttachmentError as exc:
                self._drop("no_attachment" if attachment is None else "bad_attachment", key, exc)
                return
            try:
                msg = types.deserialize(payload, ros_type)
            except Exception as exc:  # rosbags raises several kinds on bad CDR
                self._drop("malformed", key, exc)
                return
            with self._lock:
                self.counts["received"] += 1
            callback(msg, att)

        if qos.durability == TRANSIENT_LOCAL or qos.reliability == RELIABLE:
            self._sub = _advanced_subscription(node.bus, self.key, qos, on_sample)
        else:
            self._sub = node.bus.subscribe_attached(self.key, on_sample)
        self._token = node.bus.declare_absolute_token(names.endpoint_token(
            node.domain, node.zid, node.nid, self.eid, "MS", node.namespace, node.name, topic,
            ros_type, self.type_hash, qos, node.enclave))

    def _drop(self, counter: str, key: str, exc: Exception) -> None:
        with self._lock:
            self.counts[counter] += 1
            first = counter not in self._warned
            self._warned.add(counter)
        if first:
            log.warning("dropping samples on %s: %s (counted in %s)", key, exc, counter)

    def close(self) -> None:
        self._token.close()
        self._sub.close()


class Ros2Node(Closing):
    def __init__(self, bus: ZenohBus, types: Ros2Types, *, name: str, namespace: str = "/",
                 domain: int = 0, enclave: str = ""):
        if not 0 <= domain <= 232:
            raise names.Ros2NameError(f"ROS 2 domain id {domain}: expected 0–232")
        self.bus, self.types = bus, types
        self.name = name
        self.namespace = names.normalize_namespace(namespace)
        names.resolve(self.namespace, name)
        self.domain, self.enclave = domain, enclave
        self.zid = bus.zid
        self.nid = next(_ids)
        self._token = bus.declare_absolute_token(names.node_token(
            domain, self.zid, self.nid, self.namespace, name, enclave))
        self._entities: list = []

    def topic(self, name: str) -> str:
        return names.resolve(self.namespace, name)

    def publisher(self, name: str, ros_type: str, qos: Qos) -> Ros2Publisher:
        pub = Ros2Publisher(self, self.topic(name), ros_type, qos)
        self._entities.append(pub)
        return pub

    def subscription(self, name: str, ros_type: str, qos: Qos,
                     callback: Callable[[Any, Attachment], None],
                     max_payload: int | None = None) -> Ros2Subscription:
        """`max_payload`: bytes; a larger sample is dropped undecoded (counted `oversized`)."""
        sub = Ros2Subscription(self, self.topic(name), ros_type, qos, callback, max_payload)
        self._entities.append(sub)
        return sub

    def remove(self, entity: Ros2Publisher | Ros2Subscription) -> None:
        """Undeclare one publisher or subscription (its token goes with it)."""
        if entity in self._entities:
            self._entities.remove(entity)
            entity.close()

    def subscriptions(self) -> list[Ros2Subscription]:
        return [e for e in self._entities if isinstance(e, Ros2Subscription)]

    def close(self) -> None:
        for e in self._entities:
            e.close()
        self._entities.clear()
        self._token.close()

