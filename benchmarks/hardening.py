"""Hardening benchmark: the supervisor under a flood of invented ids, and the simulator beside a
stopped observer.

Prints one JSON line per figure:
  supervisor_flood        `mrta supervise patrol --json` while a publisher sends, per second,
                          FLOOD samples with unique invented task ids (on robot1's key), unique
                          invented robot ids, and the three patrol robots' valid broadcasts at
                          10 Hz; RSS of the supervisor every 5 s against its own RSS before the
                          flood (the same-run baseline), and valid samples counted vs sent
  sim_stopped_observer    wall time of `mrta sim --speed 0` (3 robots, 1,500 s simulated)
                          when an `mrta echo '**'` joins and is SIGSTOPped mid-run, against the
                          same run with no observer, measured in the same run

Run: python benchmarks/hardening.py [--seconds 60] [--flood 10000]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import time

HERE = os.path.abspath(__file__)
WARMUP = 4.0
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import ProcessGroup, mrta_argv  # noqa: E402


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return float("nan")


def child_flood(rate: float, seconds: float) -> None:
    import zenoh

    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.codec import encode, encoding_for
    from mrta_zenoh.messages import Header
    from mrta_agent.alliance.messages import InterRobotCommunication

    encoding = zenoh.Encoding(encoding_for(InterRobotCommunication.TYPE_NAME))
    sent_valid = 0
    with open_bus(BusOptions()) as bus:
        for i in (1, 2, 3):
            bus.declare_token(f"robot{i}/alliance/agent")
        print(json.dumps({"ready": True}), flush=True)
        time.sleep(WARMUP)  # the parent measures the supervisor's RSS before the flood
        t0 = time.perf_counter()
        k = 0
        next_valid = t0
        while time.perf_counter() - t0 < seconds:
            target = t0 + k / rate
            while time.perf_counter() < target:
                pass
            now = time.time()
            if k % 2:
                bus.publish("robot1/alliance/inter_robot_communication",
                            InterRobotCommunication(Header("robot1", now, k), f"task{k}", 60.0))
            else:  # a new key every time: a plain put, no publisher declared per key
                rid = f"intruder{k}"
                bus.session.put(f"{rid}/alliance/inter_robot_communication",
                                encode(InterRobotCommunication(Header(rid, now, k), "wander", 60.0)),
                                encoding=encoding)
            k += 1
            if time.perf_counter() >= next_valid:
                next_valid += 0.1
                for i, task in ((1, "wander"), (2, "border_protection"), (3, "report")):
                    bus.publish(f"robot{i}/alliance/inter_robot_communication",
                                InterRobotCommunication(Header(f"robot{i}", now, k), task, 60.0))
                    sent_valid += 1
        print(json.dumps({"sent_flood": k, "sent_valid": sent_valid,
                          "seconds": time.perf_counter() - t0}), flush=True)
        time.sleep(3.0)  # let the last samples arrive before the tokens go


def supervisor_flood(env: dict, rate: float, seconds: float) -> dict:
    with ProcessGroup(env) as group:
        sup = group.start(mrta_argv("-q", "supervise", "patrol", "--json", "--rate", "1"),
                          name="supervise")
        pub = group.start([sys.executable, HERE, "--child", str(rate), str(seconds)],
                          name="flood")
        pub.wait_json(lambda o: o.get("ready"), 60)
        sup.wait_json(lambda o: True, 60)
        time.sleep(WARMUP / 2)
        baseline = rss_mb(sup.pid)
        time.sleep(WARMUP / 2)
        samples = []
        t0 = time.monotonic()
        while True:
            if any('"sent_flood"' in x for x in pub.stdout):
                break
            if time.monotonic() - t0 >= len(samples) * 5.0:
                samples.append(round(rss_mb(sup.pid), 1))
            time.sleep(0.2)
        sent = next(json.loads(x) for x in pub.stdout if '"sent_flood"' in x)
        time.sleep(2.5)
        snap = json.loads(sup.stdout[-1])  # the latest snapshot
        c = snap["counts"]
        valid_counted = (c["samples"] - c["unknown"] - c["field_errors"] - c["key_mismatch"]
                         - c["wrong_type"])
        return {"figure": "supervisor_flood", "flood_per_s": round(sent["sent_flood"] / sent["seconds"]),
                "seconds": round(sent["seconds"], 1), "rss_before_mb": round(baseline, 1),
                "rss_every_5s_mb": samples, "rss_growth_mb": round(max(samples) - baseline, 1),
                "valid_sent": sent["sent_valid"], "valid_counted": valid_counted,
                "unknown_counted": c["unknown"], "unknown_overflow": c["unknown_overflow"],
                "alarms": len(snap["alarms"]), "snapshot_bytes": len(json.dumps(snap)),
                "target": "flat memory; every valid sample of known robots counted"}


def sim_run(env: dict, stopped_observer: bool) -> tuple[float, float]:
    """(wall seconds of the simulation loop as the simulator reports it, wall seconds from
    start to exit). With `stopped_observer`, an `mrta echo '**'` joins once the simulator runs
    and is SIGSTOPped — a publisher that waited for it would hold the world."""
    with ProcessGroup(env) as group:
        t0 = time.monotonic()
        sim = group.start(mrta_argv("sim", "--world", "patrol", "--robot", "robot1",
                                    "--robot", "robot2", "--robot", "robot3", "--speed", "0",
                                    "--duration", "1500"), name="sim")
        if stopped_observer:
            sim.wait_stderr(lambda line: "ready:" in line, 60)
            echo = group.start(mrta_argv("echo", "**", "--json"), name="observer")
            echo.wait_line(lambda line: True, 60)  # it receives: it is connected
            echo.signal(signal.SIGSTOP)
        rc = sim.wait(600)
        total = time.monotonic() - t0
        if stopped_observer:
            echo.signal(signal.SIGCONT)
        if rc != 0:
            raise RuntimeError(sim.tail())
        done = next(line for line in sim.stderr if "done:" in line)
        loop = float(done.split(" simulated in ")[1].split(" s")[0])
        return loop, total


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        child_flood(float(sys.argv[2]), float(sys.argv[3]))
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--flood", type=float, default=10_000.0)
    ap.add_argument("--only", choices=("flood", "sim"))
    args = ap.parse_args()
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error")
    if args.only != "sim":
        print(json.dumps(supervisor_flood(env, args.flood, args.seconds)), flush=True)
    if args.only == "flood":
        return
    plain = [sim_run(env, False) for _ in range(2)]
    stopped = [sim_run(env, True) for _ in range(2)]
    base, with_stopped = min(p[0] for p in plain), min(p[0] for p in stopped)
    print(json.dumps({"figure": "sim_stopped_observer", "simulated_s": 1500,
                      "loop_wall_no_observer_s": round(base, 2),
                      "loop_wall_stopped_observer_s": round(with_stopped, 2),
                      "slowdown_pct": round(100 * (with_stopped / base - 1), 1),
                      "exit_wall_no_observer_s": round(min(p[1] for p in plain), 2),
                      "exit_wall_stopped_observer_s": round(min(p[1] for p in stopped), 2),
                      "target_pct_max": 5}), flush=True)


if __name__ == "__main__":
    main()
