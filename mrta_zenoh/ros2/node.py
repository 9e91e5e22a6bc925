"""A ROS 2 node on a ZenohBus, as rmw_zenoh would make it: a node token, and per publisher or
subscription its own token, its data key and — for publishers — an attachment on every sample.

QoS as ROS expects it: a reliable publisher uses Zenoh's BLOCK congestion control, a
best-effort one DROP (a stalled subscriber never holds a sensor stream up). Subscriptions are
strict like rmw_zenoh's: a sample without a valid 33-byte attachment, or whose CDR does not
decode, is counted and dropped, never passed on. A subscription may cap the payload size: a
larger sample is counted (`oversized`) and dropped before it is decoded — decoding is what
costs (a 1M-point cloud twice a second held a core at 100 % and grew the bridge by 350 MB),
and it runs on Zenoh's thread, where it would delay every other topic (ZENOH_NOTES.md, trap 3).
"""

from __future__ import annotations

import itertools
import logging
import threading
import time
from typing import Any, Callable

from ..bus.zenoh_bus import ZenohBus
from . import names
from .attachment import Attachment, AttachmentError, Stamper
from .names import BEST_EFFORT, Qos
from .types import Ros2Types

log = logging.getLogger("mrta.ros2")
_ids = itertools.count(1)  # node and entity ids, unique in this process (as rmw_zenoh's)


class Ros2Publisher:
    def __init__(self, node: "Ros2Node", topic: str, ros_type: str, qos: Qos):
        self.topic, self.ros_type, self.qos = topic, ros_type, qos
        types = node.types
        self.type_hash = types.hash(ros_type)
        self.key = names.topic_key(node.domain, topic, ros_type, self.type_hash)
        self.eid = next(_ids)
        self.stamper = Stamper()
        self._types = types
        self._pub = node.bus.declare_attached_publisher(self.key, lossy=qos.reliability == BEST_EFFORT)
        self._token = node.bus.declare_absolute_token(names.endpoint_token(
            node.domain, node.zid, node.nid, self.eid, "MP", node.namespace, node.name, topic,
            ros_type, self.type_hash, qos, node.enclave))
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


class Ros2Node:
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

    def __enter__(self) -> "Ros2Node":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
