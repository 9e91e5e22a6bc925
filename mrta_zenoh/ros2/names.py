"""rmw_zenoh's names, as strings (rmw_zenoh_cpp of Jazzy ≥ 0.2.4, Humble ≥ 0.1.2, Kilted, Rolling
≥ 0.6.0: `liveliness_utils.cpp`, `qos.cpp`, `docs/design.md`).

* Topic key: `<domain>/<topic without outer slashes>/<pkg>::msg::dds_::<Name>_/RIHS01_<hex>`.
* Liveliness token of a node:
  `@ros2_lv/<domain>/<zid>/<nid>/<nid>/NN/<enclave>/<namespace>/<node>`; of a publisher or
  subscription the same with its own entity id and kind (MP, MS), then
  `/<topic>/<dds type>/<type hash>/<qos>`. Inside a chunk `/` is written `%`, an empty field `%`.
* QoS: `rel:dur:hist,depth:deadline:lifespan:liveliness` (deadline and lifespan `sec,nsec`,
  liveliness `kind,sec,nsec`), a field equal to rmw_zenoh's default left empty — reliable,
  volatile, keep-last, depth 42 (`RMW_ZENOH_DEFAULT_HISTORY_DEPTH`) — both ways: reliable depth
  10 is `::,10:,:,:,,`, depth 42 is `::,:,:,:,,`, and an empty depth reads as 42, not 0.
* Types: `msg`, `srv` and `action` (an action's topics and services carry types such as
  `pkg::action::dds_::Fibonacci_FeedbackMessage_`, valid names, not to be refused).
* GID: rmw_zenoh derives an entity's GID from its token — XXH3-128 of the whole key, low 64
  bits then high 64 bits, little-endian (`Entity::Entity`) — and sends it in every attachment;
  `ros2 topic info -v` shows it. We compute it the same way (`gid_of`), not at random.

Everything here is pure and has fixed test vectors (tests/test_ros2_wire.py,
tests/test_ros2_conventions.py): a wrong chunk
means silence on the ROS side, never an error (rmw_zenoh #479, #569).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ..errors import ConfigError

ADMIN_SPACE = "@ros2_lv"
KINDS = {"NN": "node", "MP": "publisher", "MS": "subscription", "SS": "service", "SC": "client"}
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
_TYPE = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)/(msg|srv|action)/([A-Za-z][A-Za-z0-9_]*)$")
_DDS = re.compile(r"^([A-Za-z][A-Za-z0-9_]*)::(msg|srv|action)::dds_::([A-Za-z][A-Za-z0-9_]*)_$")
DEFAULT_DEPTH = 42  # rmw_zenoh's default history depth, omitted from tokens
_NAME = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)*/?$")
_NODE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
# A token longer than this is refused before it is split: rmw_zenoh's are a few hundred
# characters; the cap keeps one forged key from costing more than a bounded amount of work.
MAX_TOKEN_LENGTH = 2048


class Ros2NameError(ConfigError):
    """A ROS name, type or token we cannot use (the message says which and why)."""


def dds_type(ros_type: str) -> str:
    """`geometry_msgs/msg/Twist` → `geometry_msgs::msg::dds_::Twist_`."""
    m = _TYPE.match(ros_type)
    if m is None:
        raise Ros2NameError(f"ROS 2 type {ros_type!r}: expected package/msg/Name (or srv, action)")
    return f"{m.group(1)}::{m.group(2)}::dds_::{m.group(3)}_"


def ros_type(dds: str) -> str:
    """The inverse of dds_type."""
    m = _DDS.match(dds)
    if m is None:
        raise Ros2NameError(f"DDS type {dds!r}: expected package::msg::dds_::Name_")
    return f"{m.group(1)}/{m.group(2)}/{m.group(3)}"


def resolve(namespace: str, name: str) -> str:
    """A topic's fully qualified name: `cmd_vel` in `/robot1` → `/robot1/cmd_vel`; an absolute
    name is kept. Both must be ROS names (letters, digits, `_`, `/`)."""
    for what, text in (("namespace", namespace), ("name", name)):
        if not _NAME.match(text if text.startswith("/") else "/" + text):
            raise Ros2NameError(f"ROS 2 {what} {text!r}: use letters, digits, '_' and '/'")
    if name.startswith("/"):
        full = name
    else:
        full = namespace.rstrip("/") + "/" + name
    if not full.startswith("/"):
        full = "/" + full
    return full.rstrip("/") or "/"


def normalize_namespace(namespace: str) -> str:
    ns = "/" + namespace.strip("/")
    resolve(ns, "x")
    return ns


def topic_key(domain: int, topic: str, ros_type_name: str, type_hash: str) -> str:
    """The data key of a topic (its fully qualified name)."""
    return f"{domain}/{topic.strip('/')}/{dds_type(ros_type_name)}/{type_hash}"


def mangle(text: str) -> str:
    """A name as one key chunk: `/` → `%`; empty → `%`."""
    return text.replace("/", "%") if text else "%"


def demangle(chunk: str) -> str:
    return "" if chunk == "%" else chunk.replace("%", "/")


@dataclass(frozen=True)
class Qos:
    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = 10

    def encode(self) -> str:
        """As rmw_zenoh's qos_to_keyexpr: every field equal to its default left empty (the
        depth too: it is written whatever the history, unless it is 42)."""
        rel = "" if self.reliability == RELIABLE else str(self.reliability)
        dur = "" if self.durability == VOLATILE else str(self.durability)
        hist = "" if self.history == KEEP_LAST else str(self.history)
        depth = "" if self.depth == DEFAULT_DEPTH else str(self.depth)
        return f"{rel}:{dur}:{hist},{depth}:,:,:,,"

    @classmethod
    def decode(cls, text: str) -> "Qos":
        parts = text.split(":")
        if len(parts) != 6 or "," not in parts[2]:
            raise Ros2NameError(f"QoS {text!r}: expected rel:dur:hist,depth:deadline:lifespan:liveliness")
        hist, _, depth = parts[2].partition(",")
        try:
            return cls(int(parts[0] or RELIABLE), int(parts[1] or VOLATILE), int(hist or KEEP_LAST),
                       int(depth) if depth else DEFAULT_DEPTH)
        except ValueError:
            raise Ros2NameError(f"QoS {text!r}: a field is not a number") from None


COMMANDS = Qos(RELIABLE, VOLATILE, KEEP_LAST, 10)   # what a driver's cmd_vel subscription takes
SENSOR_DATA = Qos(BEST_EFFORT, VOLATILE, KEEP_LAST, 5)  # rclcpp's SensorDataQoS


@dataclass(frozen=True)
class Entity:
    """One liveliness token of the ROS 2 graph, parsed."""

    domain: int
    zid: str
    nid: str
    eid: str
    kind: str              # NN, MP, MS, SS, SC
    enclave: str
    namespace: str         # "/robot1", or "/" for none
    node: str
    topic: str = ""        # fully qualified, for MP / MS / SS / SC
    type: str = ""         # ROS form: geometry_msgs/msg/Twist
    type_hash: str = ""
    qos: Qos | None = None

    @property
    def node_name(self) -> str:
        """Fully qualified: `/robot1/pioneer_driver`."""
        return resolve(self.namespace or "/", self.node)


def gid_of(token: str) -> bytes:
    """The 16-byte GID rmw_zenoh gives the entity of this liveliness key: XXH3-128 of the key,
    its low 64 bits then its high 64 bits, each little-endian — i.e. the canonical (big-endian)
    digest reversed."""
    import xxhash

    return xxhash.xxh3_128_digest(token.encode())[::-1]


def node_token(domain: int, zid: str, nid: int, namespace: str, node: str,
               enclave: str = "") -> str:
    return (f"{ADMIN_SPACE}/{domain}/{zid}/{nid}/{nid}/NN/{mangle(enclave)}/"
            f"{mangle(namespace if namespace != '/' else '')}/{mangle(node)}")


def endpoint_token(domain: int, zid: str, nid: int, eid: int, kind: str, namespace: str,
                   node: str, topic: str, ros_type_name: str, type_hash: str, qos: Qos,
                   enclave: str = "") -> str:
    if kind not in ("MP", "MS", "SS", "SC"):
        raise Ros2NameError(f"endpoint kind {kind!r}: expected MP, MS, SS or SC")
    return (f"{ADMIN_SPACE}/{domain}/{zid}/{nid}/{eid}/{kind}/{mangle(enclave)}/"
            f"{mangle(namespace if namespace != '/' else '')}/{mangle(node)}/{mangle(topic)}/"
            f"{dds_type(ros_type_name)}/{type_hash}/{qos.encode()}")


def parse_token(key: str) -> Entity:
    """A liveliness key as an Entity; Ros2NameError naming what is wrong otherwise.

    Everything a tool later shows or resolves is checked here, once: the namespace, the node's
    name and the topic must be ROS names, the type a ROS type. A token is forged as easily as
    it is declared (any peer may declare `@ros2_lv/…`), so a name that passed here must never
    raise later — `Entity.node_name` on a namespace `/a-b` made `mrta supervise` exit 2."""
    if len(key) > MAX_TOKEN_LENGTH:
        raise Ros2NameError(f"a liveliness token of {len(key)} characters (at most "
                            f"{MAX_TOKEN_LENGTH}): {key[:120]!r}")
    parts = key.split("/")
    if len(parts) < 9 or parts[0] != ADMIN_SPACE:
        raise Ros2NameError(f"not a ROS 2 liveliness token: {key[:120]!r}")
    kind = parts[5]
    if kind not in KINDS:
        raise Ros2NameError(f"unknown entity kind {kind!r} in {key[:120]!r}")
    try:
        domain = int(parts[1])
    except ValueError:
        raise Ros2NameError(f"domain {parts[1]!r} is not a number in {key[:120]!r}") from None
    ns = demangle(parts[7])
    ns = ns if ns.startswith("/") else "/" + ns
    node = demangle(parts[8])
    if not _NAME.match(ns):
        raise Ros2NameError(f"namespace {ns!r} is not a ROS name in {key[:120]!r}")
    if not _NODE.match(node):
        raise Ros2NameError(f"node name {node!r} is not a ROS name in {key[:120]!r}")
    common = dict(domain=domain, zid=parts[2], nid=parts[3], eid=parts[4], kind=kind,
                  enclave=demangle(parts[6]), namespace=ns, node=node)
    if kind == "NN":
        if len(parts) != 9:
            raise Ros2NameError(f"a node token has 9 chunks, this has {len(parts)}: {key[:120]!r}")
        return Entity(**common)
    if len(parts) != 13:
        raise Ros2NameError(f"an endpoint token has 13 chunks, this has {len(parts)}: {key[:120]!r}")
    topic = demangle(parts[9])
    topic = topic if topic.startswith("/") else "/" + topic
    if not _NAME.match(topic) or topic.endswith("/"):
        raise Ros2NameError(f"topic {topic!r} is not a ROS name in {key[:120]!r}")
    return Entity(**common, topic=topic,
                  type=ros_type(parts[10]), type_hash=parts[11], qos=Qos.decode(parts[12]))
