"""Tasks at run time under a burst: acceptance latency and throughput against the burst's size.

`mrta task serve` (the run's intake, on wall time: its step boundaries every 0.1 s of the
machine's clock) on a private rendezvous, and a submitter in this process sending a burst of N
submissions of the default delivery instance's task type at once (each checked as a mission's
intake checks it: typed, servable, inside the room). For each N: the latency of each submission
(sent → its answer heard, wall time: the wait for the next step boundary, ≤ 0.1 s, is part of
it) as median, 95th percentile and max, the throughput (N ÷ the time from the first send to the
last answer), and how many were accepted. The baseline, in the same run, is a burst of one: a
lone request's latency (mostly the boundary's wait). Prints one JSON line per figure.

Run: python benchmarks/task_submit.py [--bursts 1,10,100,1000,5000] [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import threading
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.bus import BusOptions, open_bus  # noqa: E402
from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import Child, mrta_argv  # noqa: E402
from mrta_zenoh.tasks.api import Submitter, TaskRequest  # noqa: E402
from mrta_zenoh.tasks.messages import Answer, Op, answer_key  # noqa: E402

ROOT = Path(HERE).parents[1]
INSTANCE = ROOT / "configs" / "applications" / "delivery" / "config" / "instance.yaml"
SPOTS = [(x + 0.5, y + 0.5) for x in range(-4, 4) for y in range(-3, 3)]


def burst(submitter: Submitter, heard: dict, lock: threading.Lock, n: int, tag: str) -> dict:
    requests = [TaskRequest(Op.SUBMIT, f"{tag}-{i}", {"position": list(SPOTS[i % len(SPOTS)]),
                                                       "service": 1.0}) for i in range(n)]
    sent = {}
    t0 = time.perf_counter()
    ids = []
    for r in requests:
        (rid,) = submitter.send([r])
        sent[rid] = time.perf_counter()
        ids.append(rid)
    answers = submitter.collect(ids, timeout=120)
    deadline = time.monotonic() + 5  # this process's other subscriber hears each answer after
    while time.monotonic() < deadline:  # the submitter's own: wait for its last stamps
        with lock:
            if all(i in heard for i in ids):
                break
        time.sleep(0.01)
    with lock:
        latencies = sorted(heard[i] - sent[i] for i in ids if i in heard)
        last = max(heard[i] for i in ids if i in heard)
    accepted = sum(a is not None and a.outcome == "accepted" for a in answers)
    q95 = latencies[min(len(latencies) - 1, int(0.95 * len(latencies)))]
    return {"burst": n, "accepted": accepted, "answered": len(latencies),
            "latency_median_ms": round(statistics.median(latencies) * 1e3, 2),
            "latency_p95_ms": round(q95 * 1e3, 2), "latency_max_ms": round(latencies[-1] * 1e3, 2),
            "throughput_per_s": round(n / (last - t0), 1)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--bursts", default="1,10,100,1000,5000")
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()
    sizes = [int(x) for x in args.bursts.split(",")]
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error")
    os.environ["MRTA_RENDEZVOUS"] = env["MRTA_RENDEZVOUS"]
    intake = Child(mrta_argv("task", "serve", "--instance", str(INSTANCE), "--burst", "100000",
                             "--rate", "100000"), name="intake", env=env)
    heard: dict[str, float] = {}
    lock = threading.Lock()
    try:
        with open_bus(BusOptions()) as bus, Submitter(bus, "bench") as submitter:
            def stamp(sample) -> None:
                with lock:
                    heard[sample.message.request] = time.perf_counter()
            sub = bus.subscribe(answer_key("bench"), stamp, msg_type=Answer)
            submitter.wait_for_intake(60)
            time.sleep(0.5)
            for r in range(args.rounds):
                for n in sizes:
                    row = burst(submitter, heard, lock, n, f"r{r}n{n}")
                    row.update(round=r, baseline="burst of 1" if n == 1 else None)
                    print(json.dumps(row), flush=True)
            sub.close()
    finally:
        intake.stop()


if __name__ == "__main__":
    main()
