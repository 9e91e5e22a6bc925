"""What N idle processes cost on a peer mesh and through a router: each opens our default bus
(`open_bus`), declares a liveliness token, a subscription and a liveliness watch — what every
agent holds — and then does nothing; CPU per process over a window once all are connected.

A peer mesh of N processes keeps N − 1 links in each, and every link sends a keep-alive four
times per lease (3 s: mrta_zenoh/bus/options.py), so an idle process's CPU grows with N; a client
of a router keeps one link. Same-run baselines: the mesh at the smaller N, and the router.

Run: python benchmarks/mesh_idle.py [--processes 20 50] [--window 15]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

HERE = os.path.abspath(__file__)
sys.path.insert(0, os.path.dirname(HERE))
from procstat import proc_stat  # noqa: E402  (benchmarks/procstat.py, beside this)
from swarm import client, start_router  # noqa: E402

sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import ProcessGroup  # noqa: E402

IDLE = """
import sys, time
from mrta_zenoh.bus import BusOptions, open_bus
mode, name, connect = sys.argv[1], sys.argv[2], sys.argv[3:]
with open_bus(BusOptions(mode=mode, connect=connect)) as bus:
    handles = [bus.declare_token(f"{name}/alive"), bus.subscribe("*/x", lambda s: None),
               bus.watch_liveliness("*/alive", lambda k, a: None)]
    print("up", flush=True)
    time.sleep(3600)
"""
SETTLE = 20.0  # wall s for every link to be up before the window


def idle(n: int, topology: str, window: float) -> dict:
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error")
    bus = client(topology, env)
    mode, connect = (bus[1], bus[3:]) if bus else ("peer", [])
    with ProcessGroup(env) as group:
        router = start_router(group, topology, env)
        procs = [group.start([sys.executable, "-c", IDLE, mode, f"p{i}", *connect],
                             name=f"p{i}") for i in range(n)]
        time.sleep(SETTLE)
        if not all(p.running() for p in procs):
            bad = next(p for p in procs if not p.running())
            raise RuntimeError(f"{bad.name} {bad.describe_exit()}:\n{bad.tail()}")
        hub = [router] if router is not None else []
        before = {p.pid: proc_stat(p.pid)[0] for p in procs + hub}
        time.sleep(window)
        after = {p.pid: proc_stat(p.pid)[0] for p in procs + hub}
    used = [after[p.pid] - before[p.pid] for p in procs]
    return {"figure": "mesh_idle", "processes": n, "topology": topology,
            "cpu_percent_of_a_core_per_process": round(sum(used) / n / window * 100, 2),
            "cpu_cores_total": round(sum(used) / window, 2),
            "router_cpu_percent_of_a_core": round(
                sum(after[p.pid] - before[p.pid] for p in hub) / window * 100, 2)
            if hub else None,
            "load_average": [round(x, 2) for x in os.getloadavg()]}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--processes", type=int, nargs="+", default=[20, 50])
    ap.add_argument("--window", type=float, default=15.0, help="wall seconds measured")
    args = ap.parse_args()
    for n in args.processes:
        for topology in ("peer", "router"):
            print(json.dumps(idle(n, topology, args.window)), flush=True)


if __name__ == "__main__":
    main()
