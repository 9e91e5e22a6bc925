"""The ROS 2 graph as rmw_zenoh's graph cache sees it: every node, publisher and subscription,
from the liveliness tokens under `@ros2_lv/<domain>/**` (what `ros2 node list` and `ros2 topic
list` read). An `@` chunk is matched only literally, so it is watched explicitly.

Fed by `on_token(key, alive)` — from a Zenoh liveliness watch (`watch`), or directly in tests —
so the same code serves `mrta ros2 graph` and the supervisor's ROS 2 section. A token that does
not parse is counted, never fatal.
"""

from __future__ import annotations

import threading
from collections import defaultdict

from .names import ADMIN_SPACE, Entity, Ros2NameError, parse_token


class Ros2Graph:
    def __init__(self, domain: int = 0):
        self.domain = domain
        self._entities: dict[str, Entity] = {}
        self._lock = threading.Lock()
        self.invalid = 0

    @property
    def key_expr(self) -> str:
        return f"{ADMIN_SPACE}/{self.domain}/**"

    def watch(self, bus) -> object:
        """Follow the graph on a ZenohBus; returns the watch (close() it)."""
        return bus.watch_absolute(self.key_expr, self.on_token)

    def on_token(self, key: str, alive: bool) -> None:
        try:
            entity = parse_token(key)
        except Ros2NameError:
            with self._lock:
                self.invalid += 1
            return
        if entity.domain != self.domain:
            return
        with self._lock:
            if alive:
                self._entities[key] = entity
            else:
                self._entities.pop(key, None)

    def entities(self) -> list[Entity]:
        with self._lock:
            return list(self._entities.values())

    def nodes(self) -> list[str]:
        """Fully qualified node names, sorted (as `ros2 node list`)."""
        return sorted({e.node_name for e in self.entities() if e.kind == "NN"})

    def robot_nodes(self) -> dict[str, list[str]]:
        """Nodes by the first chunk of their namespace (`/robot1/…` → robot1): who drives whom."""
        out: dict[str, list[str]] = defaultdict(list)
        for e in self.entities():
            if e.kind == "NN" and e.namespace.strip("/"):
                out[e.namespace.strip("/").split("/")[0]].append(e.node_name)
        return {r: sorted(v) for r, v in out.items()}

    def topics(self) -> list[dict]:
        """Every topic with its types and counts of publishers and subscriptions (as `ros2
        topic list -v`), sorted by name."""
        table: dict[str, dict] = {}
        for e in self.entities():
            if e.kind not in ("MP", "MS"):
                continue
            t = table.setdefault(e.topic, {"topic": e.topic, "types": set(), "publishers": 0,
                                           "subscriptions": 0})
            t["types"].add(e.type)
            t["publishers" if e.kind == "MP" else "subscriptions"] += 1
        return [{**t, "types": sorted(t["types"])} for _, t in sorted(table.items())]

    def snapshot(self) -> dict:
        return {"domain": self.domain, "nodes": self.nodes(), "topics": self.topics(),
                "invalid_tokens": self.invalid}


def read_graph(*, bus_options, domain: int = 0, wait: float = 1.0) -> dict:
    """The graph as seen after `wait` seconds of listening (the current tokens arrive first)."""
    from ..bus import open_bus

    graph = Ros2Graph(domain)
    with open_bus(bus_options) as bus:
        watch = graph.watch(bus)
        threading.Event().wait(wait)
        watch.close()
    return graph.snapshot()
