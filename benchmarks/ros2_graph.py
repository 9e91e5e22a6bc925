"""The supervisor's ROS 2 graph under many tokens: time and memory to take N valid tokens
(`@ros2_lv/0/…`, nodes with publishers and subscriptions, as rmw_zenoh declares them), then
to take them all away, and what a snapshot costs at that size. In-process: tokens go straight
to `Supervisor.on_ros2_token`, as the liveliness watch would hand them over.

    python benchmarks/ros2_graph.py [--tokens 20000] [--budget 120]

One JSON line per figure. `--budget` stops the feed after that many seconds (the figure then
says how many tokens it reached), so a graph whose cost grew quadratically would still end.
"""

from __future__ import annotations

import argparse
import gc
import json
import resource
import time

from mrta_zenoh.ros2 import names
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.state import Supervisor

HASH = "RIHS01_" + "0" * 64


def tokens(n: int) -> list[str]:
    """n tokens: one node and 9 endpoints per node, in 50 namespaces (a fleet's robots)."""
    out: list[str] = []
    i = 0
    while len(out) < n:
        ns = f"/fleet{i % 50}"
        node = f"node{i}"
        out.append(names.node_token(0, f"z{i:x}", 1, ns, node))
        for e in range(9):
            kind = "MP" if e % 2 else "MS"
            out.append(names.endpoint_token(0, f"z{i:x}", 1, 2 + e, kind, ns, node,
                                            f"{ns}/topic{e}", "std_msgs/msg/String", HASH,
                                            names.COMMANDS))
        i += 1
    return out[:n]


def rss_mb() -> float:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--tokens", type=int, default=20_000)
    ap.add_argument("--budget", type=float, default=120.0)
    a = ap.parse_args()
    keys = tokens(a.tokens)
    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)
    gc.collect()
    rss0 = rss_mb()
    cpu0, t0 = resource.getrusage(resource.RUSAGE_SELF).ru_utime, time.perf_counter()
    fed = 0
    for k in keys:
        sup.on_ros2_token(k, True, 1.0)
        fed += 1
        if fed % 500 == 0 and time.perf_counter() - t0 > a.budget:
            break
    wall = time.perf_counter() - t0
    cpu = resource.getrusage(resource.RUSAGE_SELF).ru_utime - cpu0
    gc.collect()
    print(json.dumps({"figure": "add tokens", "tokens": fed, "of": a.tokens,
                      "seconds": round(wall, 2), "cpu_seconds": round(cpu, 2),
                      "rss_growth_mb": round(rss_mb() - rss0, 1),
                      "in_graph": len(sup.ros2.entities()) if hasattr(sup.ros2, "entities")
                      else sup.ros2.size}))
    t1 = time.perf_counter()
    snap = sup.snapshot(2.0)
    print(json.dumps({"figure": "snapshot", "seconds": round(time.perf_counter() - t1, 3),
                      "nodes": len(snap["ros2"]["nodes"]),
                      "topics": len(snap["ros2"]["topics"]),
                      "counts": {k: v for k, v in snap["ros2"].items()
                                 if k not in ("nodes", "topics")}}))
    t2 = time.perf_counter()
    for k in keys[:fed]:
        sup.on_ros2_token(k, False, 3.0)
        if time.perf_counter() - t2 > a.budget:
            break
    print(json.dumps({"figure": "remove tokens", "seconds": round(time.perf_counter() - t2, 2),
                      "nodes_left": len(sup.snapshot(4.0)["ros2"]["nodes"])}))


if __name__ == "__main__":
    main()
