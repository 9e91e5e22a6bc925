"""The ROS 2 graph as rmw_zenoh's graph cache sees it: every node, publisher, subscription,
service server and client, from the liveliness tokens under `@ros2_lv/<domain>/**` (what `ros2
node list`, `ros2 topic list` and `ros2 service list` read; an action shows as its
`/<name>/_action/…` topics and services). An `@` chunk is matched only literally, so it is
watched explicitly.

Fed by `on_token(key, alive)` — from a Zenoh liveliness watch (`watch`), or directly in tests —
so the same code serves `mrta ros2 graph` and the supervisor's ROS 2 section.

Anybody on the bus may declare such a token, so the graph is built for hostile input:

* a token that does not parse (names.parse_token checks every name a tool shows) is counted
  (`invalid`) and never fatal; while any such token lives (`invalid_live`, tracked up to
  MAX_INVALID keys) the supervisor raises `ros2_invalid_token`;
* the graph holds at most `max_tokens` tokens (MAX_TOKENS by default, ≈ 1,000 rclcpp nodes
  with their usual endpoints): a token beyond is refused and counted (`overflow`); while any
  refused token may still live (`refused_live`: refusals minus deletions of tokens the graph
  does not hold) the picture is incomplete and the supervisor raises `ros2_graph_full`;
* it is linear: each token updates counters (nodes, nodes per robot, topics with their types
  and endpoint counts) in O(1); nothing is rescanned per token. Only the token keys are kept,
  not parsed entities: a deletion parses its key again, which costs less memory than a cache.
"""

from __future__ import annotations

import threading
from collections import Counter
from typing import NamedTuple

from .names import ADMIN_SPACE, Ros2NameError, parse_token

MAX_TOKENS = 10_000
MAX_INVALID = 100  # live invalid token keys remembered (the count goes on beyond)


class _Topic:
    """A topic (publishers, subscriptions) or a service (servers, clients: the same counters)."""

    __slots__ = ("types", "publishers", "subscriptions")

    def __init__(self) -> None:
        self.types: Counter[str] = Counter()
        self.publishers = 0
        self.subscriptions = 0


class Change(NamedTuple):
    """What one token changed: the robot (first chunk of a node's namespace) whose set of
    nodes changed, if any."""

    robot: str | None = None


NO_CHANGE = Change()


def robot_of(namespace: str) -> str | None:
    """`/robot1/sensors` → robot1; `/` → None (a node outside any robot's namespace)."""
    ns = namespace.strip("/")
    return ns.split("/", 1)[0] if ns else None


class Ros2Graph:
    def __init__(self, domain: int = 0, max_tokens: int = MAX_TOKENS):
        self.domain = domain
        self.max_tokens = max_tokens
        self._lock = threading.Lock()
        self._live: set[str] = set()                     # keys counted below
        self._nodes: Counter[str] = Counter()            # node name → NN tokens
        self._robots: dict[str, Counter[str]] = {}       # robot → node name → NN tokens
        self._topics: dict[str, _Topic] = {}
        self._services: dict[str, _Topic] = {}
        self._invalid_live: set[str] = set()
        self.invalid = 0        # tokens that did not parse, ever
        self.overflow = 0       # tokens refused because the graph was full, ever
        self.refused_live = 0   # refused tokens not yet seen deleted

    @property
    def key_expr(self) -> str:
        return f"{ADMIN_SPACE}/{self.domain}/**"

    def watch(self, bus) -> object:
        """Follow the graph on a ZenohBus; returns the watch (close() it)."""
        return bus.watch_absolute(self.key_expr, self.on_token)

    # ------------------------------------------------------------------------------ input

    def on_token(self, key: str, alive: bool) -> Change:
        """Take one token event; never raises on what the network sent."""
        try:
            entity = parse_token(key)
        except Ros2NameError:
            with self._lock:
                if alive:
                    self.invalid += 1
                    if len(self._invalid_live) < MAX_INVALID:
                        self._invalid_live.add(key)
                else:
                    self._invalid_live.discard(key)
            return NO_CHANGE
        if entity.domain != self.domain:
            return NO_CHANGE
        with self._lock:
            if alive:
                if key in self._live:
                    return NO_CHANGE
                if len(self._live) >= self.max_tokens:
                    self.overflow += 1
                    self.refused_live += 1
                    return NO_CHANGE
                self._live.add(key)
                return self._count(entity, 1)
            if key not in self._live:
                if self.refused_live:
                    self.refused_live -= 1
                return NO_CHANGE
            self._live.discard(key)
            return self._count(entity, -1)

    def _count(self, e, d: int) -> Change:
        if e.kind == "NN":
            name = e.node_name
            self._bump(self._nodes, name, d)
            robot = robot_of(e.namespace)
            if robot is None:
                return NO_CHANGE
            nodes = self._robots.setdefault(robot, Counter())
            self._bump(nodes, name, d)
            if not nodes:
                del self._robots[robot]
            return Change(robot)
        table = self._topics if e.kind in ("MP", "MS") else self._services
        t = table.get(e.topic)
        if t is None:
            t = table[e.topic] = _Topic()
        self._bump(t.types, e.type, d)
        if e.kind in ("MP", "SS"):
            t.publishers += d
        else:
            t.subscriptions += d
        if not t.types:
            del table[e.topic]
        return NO_CHANGE

    @staticmethod
    def _bump(counter: Counter, key: str, d: int) -> None:
        n = counter[key] + d
        if n > 0:
            counter[key] = n
        else:
            del counter[key]

    # ----------------------------------------------------------------------------- output

    @property
    def size(self) -> int:
        return len(self._live)

    @property
    def invalid_live(self) -> int:
        return len(self._invalid_live)

    def has_nodes(self, robot: str) -> bool:
        """Whether a node lives in the robot's namespace (`/robot1/…`)."""
        with self._lock:
            return robot in self._robots

    def nodes(self) -> list[str]:
        """Fully qualified node names, sorted (as `ros2 node list`)."""
        with self._lock:
            return sorted(self._nodes)

    def robot_nodes(self) -> dict[str, list[str]]:
        """Nodes by the first chunk of their namespace (`/robot1/…` → robot1): who drives whom."""
        with self._lock:
            return {r: sorted(v) for r, v in self._robots.items()}

    def topics(self) -> list[dict]:
        """Every topic with its types and counts of publishers and subscriptions (as `ros2
        topic list -v`), sorted by name."""
        with self._lock:
            return [{"topic": name, "types": sorted(t.types), "publishers": t.publishers,
                     "subscriptions": t.subscriptions}
                    for name, t in sorted(self._topics.items())]

    def services(self) -> list[dict]:
        """Every service with its types and counts of servers and clients (as `ros2 service
        list -t`), sorted by name."""
        with self._lock:
            return [{"service": name, "types": sorted(t.types), "servers": t.publishers,
                     "clients": t.subscriptions}
                    for name, t in sorted(self._services.items())]

    def snapshot(self) -> dict:
        return {"domain": self.domain, "nodes": self.nodes(), "topics": self.topics(),
                "services": self.services(),
                "tokens": self.size, "max_tokens": self.max_tokens,
                "invalid_tokens": self.invalid, "overflow": self.overflow}


def read_graph(*, bus_options, domain: int = 0, wait: float = 1.0) -> dict:
    """The graph as seen after `wait` seconds of listening (the current tokens arrive first)."""
    from ..bus import open_bus

    graph = Ros2Graph(domain)
    with open_bus(bus_options) as bus:
        watch = graph.watch(bus)
        threading.Event().wait(wait)
        watch.close()
    return graph.snapshot()
