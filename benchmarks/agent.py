"""Agent benchmark: high-level tick cost vs robots heard, and CPU / RSS of real agent processes.

Prints one JSON line per figure:
  tick_us          HighLevel.tick() for 10 / 100 / 1,000 other robots heard × 3 behaviour sets
                   (all at 0.5 Hz; and 1,000 heard of which 10 broadcast between two ticks),
                   with the baseline of the same tick with nobody heard; on_broadcast() apart
  agent_process    CPU share and RSS of N `mrta agent` processes at the reference rates
                   (reference robot1 parameters; sensors fed at 10 Hz), for N = 1 and 20,
                   beside a bare Zenoh session process's RSS (same rendezvous, same flags)
  agent_imports    `python -X importtime` of one `mrta agent` process at the reference
                   parameters: the total, the 10 modules of largest cumulative time, and which
                   of the libraries an agent must not load (numpy, matplotlib, rich, foxglove,
                   rosbags, cryptography) it imported — none (tests/test_agent_imports.py
                   checks the same in the suite)

The reference parameters are the repository's copy (tests/data/reference/alliance_test), so a
clone runs this as it is.

Run: python benchmarks/agent.py [--seconds 20] [--only tick|imports|processes]
"""

from __future__ import annotations

import argparse
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from procstat import private_mb, proc_stat  # benchmarks/procstat.py, beside this script

ROOT = Path(__file__).resolve().parent.parent
REF = ROOT / "tests" / "data" / "reference" / "alliance_test" / "config"
HEAVY = ("numpy", "matplotlib", "rich", "foxglove", "rosbags", "cryptography")


def tick_cost() -> None:
    """tick() alone (what it costs follows the teammates heard since the last tick)
    and on_broadcast() per message, timed apart; the baseline is the same tick, nobody heard."""
    from mrta_agent.alliance.high_level import HighLevel
    from mrta_agent.alliance.params import BehaviourSetParams, RobotParams

    sets = tuple(BehaviourSetParams(t, 100.0, 150.0, 75.0, 110.0, 5.0, "x", ()) for t in
                 ("wander", "border_protection", "report"))
    params = RobotParams("R", 2.0, 0.5, 10.0, 10.0, (), sets)
    baseline = None
    # (heard, broadcasting): all heard at 0.5 Hz (a quarter of them per 2 Hz tick, as before),
    # or only `broadcasting` of them heard between two ticks (the others unchanged)
    for n, talking in ((0, 0), (10, None), (100, None), (1000, None), (1000, 10)):
        hl = HighLevel("me", params)
        now = 0.0
        for i in range(n):
            hl.on_broadcast(f"r{i}", sets[i % 3].task_id, 100.0, now)
        reps = 2000 if n <= 100 else 300
        tick_s = heard_s = 0.0
        messages = 0
        for k in range(reps):
            now += 0.5
            for task in hl.sets:
                hl.on_feedback(task, True, now)
            who = (range(n) if k % 4 == 0 else ()) if talking is None else \
                [(k * talking + j) % n for j in range(talking)]
            t0 = time.perf_counter()
            for i in who:  # each robot broadcasts at 0.5 Hz, we tick at 2 Hz
                hl.on_broadcast(f"r{i}", sets[i % 3].task_id, 100.0, now - 0.1)
            t1 = time.perf_counter()
            hl.tick(now)
            tick_s += time.perf_counter() - t1
            heard_s += t1 - t0
            messages += len(who)
        us = tick_s / reps * 1e6
        if n == 0:
            baseline = us
            continue
        print(json.dumps({"figure": "tick_us", "robots_heard": n, "behaviour_sets": 3,
                          "heard_between_ticks": round(messages / reps, 1),
                          "tick_us": round(us, 1), "baseline_nobody_heard_us": round(baseline, 1),
                          "on_broadcast_us": round(heard_s / max(messages, 1) * 1e6, 2),
                          "ticks_per_s_of_one_core_with_broadcasts":
                              round(reps / (tick_s + heard_s))}), flush=True)


def numpy_loaded(proc: subprocess.Popen) -> bool:
    """Is numpy's extension mapped into the process (it is loaded only when a plugin draws)?"""
    with open(f"/proc/{proc.pid}/maps") as f:
        return any("_multiarray_umath" in line for line in f)


BARE_SESSION = """
import time
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session
with open_session(BusOptions()):
    time.sleep(3600)
"""


def reference_tasks(tmp: Path) -> Path:
    """The reference tasks need the patrol layers; the same tasks, no layers."""
    tf = tmp / "tasks.yaml"
    tf.write_text("tasks:\n  size: 3\n" + "".join(
        f"  task{i}:\n    id: '{t}'\n    name: '{t}'\n    layers:\n      size: 0\n"
        for i, t in enumerate(("wander", "border_protection", "report"))))
    return tf


def private_env() -> dict:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    return dict(os.environ, MRTA_RENDEZVOUS=f"tcp/127.0.0.1:{port}", RUST_LOG="error")


def agent_argv(robot: str, tasks: Path, python_flags: tuple[str, ...] = ()) -> list[str]:
    rf = REF / f"robot{(int(robot[5:]) - 1) % 5 + 1}_alliance_params.yaml"
    return [sys.executable, *python_flags, "-m", "mrta_zenoh.cli.main", "agent", robot,
            "--robot-params", str(rf), "--tasks-params", str(tasks)]


def import_time(seconds: float = 4.0) -> None:
    """One agent started under `python -X importtime`, run `seconds` (its plugins load and
    its first ticks run: a lazy import that happens then counts too), then ended by PID."""
    env = private_env()
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.Popen(agent_argv("robot1", reference_tasks(Path(tmp)),
                                           ("-X", "importtime")), env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        try:
            time.sleep(seconds)
        finally:
            proc.terminate()
            _, err = proc.communicate(timeout=30)
    rows = []  # (cumulative µs, self µs, module)
    for line in err.splitlines():
        if not line.startswith("import time:") or "imported package" in line:
            continue
        own, cumulative, name = line[len("import time:"):].split("|")
        rows.append((int(cumulative), int(own), name.strip()))
    loaded = {r[2].split(".")[0] for r in rows}
    top = sorted(rows, reverse=True)[:10]
    print(json.dumps({"figure": "agent_imports", "modules": len(rows),
                      "total_ms": round(sum(r[1] for r in rows) / 1e3, 1),
                      "top10_cumulative_ms": {r[2]: round(r[0] / 1e3, 1) for r in top},
                      "forbidden_imported": sorted(loaded & set(HEAVY)),
                      "forbidden": list(HEAVY)}), flush=True)
    if loaded & set(HEAVY):
        raise SystemExit(f"the agent imported {sorted(loaded & set(HEAVY))}")


def agents(n: int, seconds: float) -> None:
    env = private_env()
    tmp = Path(tempfile.mkdtemp())
    tf = reference_tasks(tmp)
    robots = [f"robot{i + 1}" for i in range(n)]
    feeder = subprocess.Popen([sys.executable, str(ROOT / "tests" / "procs" / "sensor_feeder.py"), *robots],
                              env=env, stdout=subprocess.PIPE, text=True)
    feeder.stdout.readline()
    procs = []
    for r in robots:
        procs.append(subprocess.Popen(agent_argv(r, tf), env=env, stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
    # the same-run baseline: a bare zenoh-python session on the same rendezvous, doing nothing
    bare = subprocess.Popen([sys.executable, "-c", BARE_SESSION], env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(5.0)  # start-up (imports, session) is not steady state
        start = [proc_stat(p.pid) for p in procs]
        t0 = time.monotonic()
        time.sleep(seconds)
        dt = time.monotonic() - t0
        end = [proc_stat(p.pid) for p in procs]
        cpu = [(e[0] - s[0]) / dt * 100 for s, e in zip(start, end)]
        rss = [e[1] / 2**20 for e in end]
        uss = [private_mb(p.pid) for p in procs]
        bare_rss = proc_stat(bare.pid)[1] / 2**20
        bare_uss = private_mb(bare.pid)
        print(json.dumps({"figure": "agent_process", "agents": n, "seconds": round(dt, 1),
                          "cpu_percent_of_a_core_mean": round(sum(cpu) / n, 2),
                          "cpu_percent_of_a_core_max": round(max(cpu), 2),
                          "rss_mb_mean": round(sum(rss) / n, 1), "rss_mb_max": round(max(rss), 1),
                          "baseline_bare_zenoh_session_rss_mb": round(bare_rss, 1),
                          "uss_mb_mean": round(sum(uss) / n, 1),
                          "baseline_bare_zenoh_session_uss_mb": round(bare_uss, 1),
                          "agents_with_numpy_loaded": sum(map(numpy_loaded, procs)),
                          "load_average": [round(x, 2) for x in os.getloadavg()],
                          "target_cpu_percent": 1.0, "target_rss_mb": 40}), flush=True)
    finally:
        for p in procs + [feeder, bare]:
            p.terminate()
        for p in procs + [feeder, bare]:
            p.wait(10)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--only", choices=("tick", "imports", "processes"))
    args = ap.parse_args()
    if args.only in (None, "tick"):
        tick_cost()
    if args.only in (None, "imports"):
        import_time()
    if args.only in (None, "processes"):
        agents(1, args.seconds)
        agents(20, args.seconds)


if __name__ == "__main__":
    main()
