"""Simulator benchmark: real-time factor for 3–1,000 robots, with and without the bus.

Prints one JSON line per figure. Each line carries the figure for our batched simulator and a
baseline measured in the same run: the same world simulated the obvious way (a Python loop over
pymunk bodies for control, one `segment_query_first` per sonar beam), so the numbers say what
numpy batching buys. "with bus" publishes clock, sonar, odom, ground truth and bumper (the
bumper on change and once a simulated second) over real Zenoh while a separate subscriber
process receives it (spawned, never forked; sensor data are best effort, so a subscriber that
falls behind loses samples: `samples_received`). Beside it: the seconds per simulated second
our sensor publishing costs (encoding and puts, the sonar sweep excluded) and what raw
zenoh-python puts of as many samples cost in the same run. Each robot count runs `--rounds`
alternating rounds (ours, naive, ours with the bus) and prints medians with their range.

Run: python benchmarks/sim.py [--robots 3 10 100 300 1000] [--seconds 10] [--rounds 3]
     [--plot PNG]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import threading
import time

import numpy as np
import pymunk

from mrta_zenoh.bus.options import private_rendezvous
from mrta_simulator.engine import DT, SENSOR_EVERY, Simulation
from mrta_simulator.world import Pose, World


def arena(n: int) -> tuple[World, dict[str, Pose]]:
    """A square arena with robots on a 3 m grid: ~similar crowding at every size."""
    side = max(10, math.ceil(math.sqrt(n)))
    half = side * 3.0 / 2 + 2.0
    walls = np.array([[-half, -half, half, -half], [half, -half, half, half],
                      [half, half, -half, half], [-half, half, -half, -half]], dtype=float)
    rng = np.random.default_rng(0)
    poses = {}
    for i in range(n):
        gx, gy = i % side, i // side
        poses[f"robot{i}"] = Pose(-half + 2.0 + gx * 3.0, -half + 2.0 + gy * 3.0,
                                  float(rng.uniform(-math.pi, math.pi)))
    return World("arena", walls), poses


def commands(n: int) -> np.ndarray:
    rng = np.random.default_rng(1)
    return np.stack([rng.uniform(0.2, 0.6, n), rng.uniform(-0.5, 0.5, n)], axis=1)


def run_ours(n: int, seconds: float) -> float:
    world, poses = arena(n)
    sim = Simulation(world, poses)
    cmd = commands(n)
    t0 = time.perf_counter()
    for k in range(int(seconds / DT)):
        if k % SENSOR_EVERY == 0:
            sim.cmd[:] = cmd  # what SimNode does for every robot with a fresh command
            sim.cmd_time[:] = sim.time
            sim.sonar()
        sim.step()
    return seconds / (time.perf_counter() - t0)


def run_naive(n: int, seconds: float) -> float:
    """Per-body Python: set each velocity, step, read each pose, one ray cast per beam."""
    world, poses = arena(n)
    space = pymunk.Space()
    for x1, y1, x2, y2 in world.walls:
        space.add(pymunk.Segment(space.static_body, (x1, y1), (x2, y2), 0.02))
    bodies, shapes = [], []
    for p in poses.values():
        b = pymunk.Body(9.0, pymunk.moment_for_circle(9.0, 0, 0.26))
        b.position, b.angle = (p.x, p.y), p.theta
        s = pymunk.Circle(b, 0.26)
        space.add(b, s)
        bodies.append(b)
        shapes.append(s)
    sonars = [(0.069, 0.136, 90), (0.114, 0.119, 50), (0.148, 0.078, 30), (0.166, 0.027, 10),
              (0.166, -0.027, -10), (0.148, -0.078, -30), (0.114, -0.119, -50),
              (0.069, -0.136, -90)]
    cmd = commands(n).tolist()
    t0 = time.perf_counter()
    for k in range(int(seconds / DT)):
        for b, (v, w) in zip(bodies, cmd):
            a = b.angle
            b.velocity = (v * math.cos(a), v * math.sin(a))
            b.angular_velocity = w
        space.step(DT)
        if k % SENSOR_EVERY == 0:
            for b, s in zip(bodies, shapes):
                flt = pymunk.ShapeFilter(group=1)
                s.filter = flt
                for sx, sy, th in sonars:
                    o = b.local_to_world((sx, sy))
                    a = b.angle + math.radians(th)
                    space.segment_query_first(o, (o.x + 5 * math.cos(a), o.y + 5 * math.sin(a)),
                                              0, flt)
                s.filter = pymunk.ShapeFilter()
    return seconds / (time.perf_counter() - t0)


# A raw zenoh-python receiver, opened with our loopback defaults (it joins $MRTA_RENDEZVOUS).
SUBSCRIBER = r"""
import sys
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session
n = [0]
with open_session(BusOptions()) as s:
    sub = s.declare_subscriber("**", lambda smp: n.__setitem__(0, n[0] + 1))
    tok = s.liveliness().declare_token("bench/subscriber")
    print("ready", flush=True)
    sys.stdin.readline()
    print(n[0], flush=True)
"""


def run_with_bus(n: int, seconds: float) -> tuple[float, int]:
    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_simulator.node import SimNode

    endpoint = private_rendezvous()
    os.environ["MRTA_RENDEZVOUS"] = endpoint
    world, poses = arena(n)
    sim = Simulation(world, poses)
    with open_bus(BusOptions()) as bus:
        seen = threading.Event()
        watch = bus.watch_liveliness("bench/subscriber", lambda k, alive: alive and seen.set())
        sub = subprocess.Popen([sys.executable, "-c", SUBSCRIBER], text=True,
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE)
        try:
            sub.stdout.readline()
            seen.wait(10)
            time.sleep(0.5)
            node = SimNode(sim, bus, speed=0.0)
            cmd = commands(n)
            sim.cmd[:] = cmd
            sim.cmd_time[:] = 1e12  # never stale: stands in for agents' steady commands
            # warm-up, not timed: the first sensor period declares every key's publisher
            # (≈ 30 µs each, once per key for the whole run)
            node.run(threading.Event(), duration=0.2)
            # time spent publishing sensor data (encoding + puts, the sonar sweep excluded)
            spent = {"publish": 0.0, "sonar": 0.0}
            node.publish_all = timed(node.publish_all, spent, "publish")
            sim.sonar = timed(sim.sonar, spent, "sonar")
            stats = node.run(threading.Event(), duration=0.2 + seconds)
            node.close()
            raw_us = raw_put_us(bus.session, n)
            time.sleep(1.0)
            sub.stdin.write("\n")
            sub.stdin.flush()
            received = int(sub.stdout.readline())
        finally:
            sub.wait(10)
            watch.close()
    publish_s = (spent["publish"] - spent["sonar"]) / stats.sim_time
    return stats.real_time_factor, received, raw_us, publish_s


def timed(fn, spent: dict, name: str):
    """fn, adding its wall time to spent[name]."""
    def wrapper(*args):
        t0 = time.perf_counter()
        try:
            return fn(*args)
        finally:
            spent[name] += time.perf_counter() - t0
    return wrapper


def raw_put_us(session, n: int, rounds: int = 10) -> float:
    """The same-run baseline: µs per raw zenoh-python put of a sonar-sized payload (≈ 200 B)
    on n keys, to the same subscriber process — the floor under our per-sample cost."""
    import zenoh
    pubs = [session.declare_publisher(f"bench/raw/{i}",
                                      congestion_control=zenoh.CongestionControl.DROP)
            for i in range(n)]
    payload = bytes(200)
    t0 = time.perf_counter()
    for _ in range(rounds):
        for p in pubs:
            p.put(payload)
    us = (time.perf_counter() - t0) / (rounds * n) * 1e6
    for p in pubs:
        p.undeclare()
    return us


def plot(curve: list[tuple[int, float, float, float]], path: str) -> None:
    """Real-time factor against robots, log-log: ours without and with the bus, and the naive
    loop measured in the same run."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [c[0] for c in curve]
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    for i, (label, style) in enumerate((("ours, no bus", "o-"), ("ours, with the bus", "s-"),
                                        ("naive pymunk loop (baseline)", "x--")), start=1):
        ax.plot(n, [c[i] for c in curve], style, label=label)
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("robots")
    ax.set_ylabel("real-time factor (simulated s per wall s)")
    ax.legend()
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--robots", type=int, nargs="+", default=[3, 10, 100, 300, 1000])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rounds", type=int, default=3,
                    help="alternating rounds of ours / naive / ours with the bus per robot "
                    "count; figures are their medians (one run swings ±25 %% at 1,000 robots "
                    "on 2 cores: the receiving process competes for the second core)")
    ap.add_argument("--plot", metavar="PNG", help="also draw the curve of real-time factor "
                    "against robots (e.g. benchmarks/img/rtf.png)")
    args = ap.parse_args()
    curve = []
    for n in args.robots:
        secs = args.seconds if n < 1000 else max(5.0, args.seconds / 2)
        rows = []
        for _ in range(args.rounds):
            ours = run_ours(n, secs)
            naive = run_naive(n, min(secs, 2.0) if n >= 100 else secs)
            rows.append((ours, naive, *run_with_bus(n, secs)))
        ours, naive, bus_rtf, received, raw_us, publish_s = \
            (statistics.median(col) for col in zip(*rows))
        spread = {name: [round(min(col), 1), round(max(col), 1)]
                  for name, col in zip(("ours", "naive", "bus"), zip(*rows))}
        print(json.dumps({"figure": "real_time_factor_no_bus", "robots": n, "ours": round(ours, 1),
                          "baseline_naive_pymunk": round(naive, 1),
                          "ratio": round(ours / naive, 2), "rounds": args.rounds,
                          "ours_range": spread["ours"], "naive_range": spread["naive"]}),
              flush=True)
        # clock at 50 Hz, three sensor samples at 10 Hz, the bumpers' heartbeat at 1 Hz (their
        # changes, 0–2 % of the robots per period here, left out)
        puts = secs * 50 + secs * 10 * 3 * n + secs * n
        print(json.dumps({"figure": "real_time_factor_with_bus", "robots": n,
                          "ours": round(bus_rtf, 1), "baseline_naive_pymunk": round(naive, 1),
                          "ratio_to_naive": round(bus_rtf / naive, 2),
                          "ours_range": spread["bus"], "rounds": args.rounds,
                          "samples_received": int(received),
                          "baseline_raw_zenoh_put_us": round(raw_us, 2),
                          "raw_put_seconds_per_simulated_second": round(
                              raw_us * 1e-6 * puts / secs, 3),
                          "ours_sensor_publish_seconds_per_simulated_second": round(publish_s, 3),
                          "ours_no_bus": round(ours, 1)}), flush=True)
        curve.append((n, ours, bus_rtf, naive))
    if args.plot:
        plot(curve, args.plot)


if __name__ == "__main__":
    main()
