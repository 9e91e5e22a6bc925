"""Lockstep benchmark: what reproducibility costs, and what experiments gain from parallel runs.

Prints one JSON line per figure:
  lockstep_patrol       the patrol mission (3 agents, 300 s simulated) at --speed 0: real-time
                        factor in lockstep, against the same mission without lockstep (agents
                        following the clock as fast as they can) in the same run
  lockstep_step_cost    wall time per physics step with N participants that answer every step
                        (10 and 100, hosted by 2 processes), against the same simulator with no
                        participant in the same run, and against the bare bus round trip: one
                        Step published, the N StepDones received and decoded, nothing else (no
                        simulator, no barrier) — what the transport alone costs; the barrier's
                        own cost is the difference
  experiment_20_runs    20 patrol runs (60 s each) through `mrta experiment --jobs 2`, against
                        20 × the wall time of one run measured in the same run
  lockstep_attack       what one forger costs a lockstep fleet on an open bus (2 agents, speed
                        4; the forgers of tests/procs/lockstep_forger.py): the longest
                        wall-time pause of an agent's own time (the gap between two of its
                        motivation samples) in the 25 s after the forgery began, against the
                        longest in the 10 s before it, in the same run; and the forgiveness
                        pauses the run's status counted

Run: python benchmarks/lockstep.py [--only patrol|steps|experiment|attacks]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import ProcessGroup, mrta_argv  # noqa: E402

CONFIG = Path(__file__).resolve().parent.parent / "configs" / "applications" / "patrol" / "config"


def sim_rtf(line: str) -> tuple[float, float]:
    m = re.search(r"done: ([\d.]+) s simulated in ([\d.]+) s", line)
    return float(m.group(1)), float(m.group(2))


def patrol(env: dict, lockstep: bool, seconds: float = 300.0) -> float:
    with ProcessGroup(env) as group:
        for r in (1, 2, 3):
            group.start(mrta_argv("-q", "agent", f"robot{r}", "--robot-params",
                                  CONFIG / f"robot{r}_alliance_params.yaml", "--tasks-params",
                                  CONFIG / "tasks_alliance_params.yaml", "--layers-params",
                                  CONFIG / "layers_alliance_params.yaml", "--sim-time"),
                        name=f"robot{r}")
        sim = group.start(mrta_argv("sim", "--world", "patrol", "--robot", "robot1", "--robot",
                                    "robot2", "--robot", "robot3", "--speed", "0", "--duration",
                                    str(seconds), "--wait-robots", "60",
                                    *(["--lockstep"] if lockstep else [])), name="sim")
        sim.wait(900)
        simulated, wall = sim_rtf(next(x for x in sim.stderr if "done:" in x))
        return simulated / wall


def child_participants(first: int, count: int) -> None:
    """Fake participants: answer every step at once, asking to be woken at the next one (for
    the step's run: the barrier drops an answer for another run)."""
    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.lifecycle import stop_on_signals
    from mrta_zenoh.lockstep.protocol import DONE, PARTICIPANT, STEP, Step, StepDone

    with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
        names = [f"fake{i}" for i in range(first, first + count)]

        def on_step(sample):
            s = sample.message
            for n in names:
                bus.publish(f"{DONE}/{n}", StepDone(n, s.stamp, {}, s.stamp + 0.015,
                                                           s.run))

        bus.subscribe(STEP, on_step, msg_type=Step)
        tokens = [bus.declare_token(f"{PARTICIPANT}/{n}") for n in names]
        print("ready", flush=True)
        stop.wait()  # until the benchmark ends this process (SIGINT)
        for t in tokens:
            t.close()


def start_participants(group: ProcessGroup, participants: int) -> None:
    """The fake participants, in two processes, each ready (its tokens declared)."""
    per = participants // 2
    for k in range(2):
        c = group.start([sys.executable, HERE, "--child", str(k * per), str(per)],
                        name=f"participants{k}")
        c.wait_line(lambda line: line == "ready", 60)


def step_cost(env: dict, participants: int, seconds: float) -> float:
    with ProcessGroup(env) as group:
        start_participants(group, participants)
        args = ["sim", "--world", "patrol", "--robot", "robot1", "--speed", "0", "--duration",
                str(seconds)]
        if participants:
            args.append("--lockstep")
        sim = group.start(mrta_argv(*args), name="sim")
        sim.wait(900)
        ready = next(x for x in sim.stderr if "ready:" in x)
        if participants and f"lockstep with {participants} participants" not in ready:
            raise RuntimeError(f"the participants did not join: {ready}")
        simulated, wall = sim_rtf(next(x for x in sim.stderr if "done:" in x))
        return wall / (simulated / 0.02)


BARE = """
import sys, threading, time
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lockstep.protocol import DONE, STEP, Step, StepDone
n, steps = int(sys.argv[1]), int(sys.argv[2])
cond, got = threading.Condition(), [0]
def on_done(sample):
    with cond:
        got[0] += 1
        if got[0] >= n:
            cond.notify_all()
with open_bus(BusOptions()) as bus:
    bus.subscribe(f"{DONE}/*", on_done, msg_type=StepDone)
    time.sleep(2.0)  # the participants' sessions reach this one
    for k in range(steps + steps // 10):
        if k == steps // 10:  # the first tenth warms up
            t0 = time.perf_counter()
        with cond:
            got[0] = 0
        bus.publish(STEP, Step(0.02 * k, k + 1, b"", run="bare-x0", timeout=2.5))
        with cond:
            while got[0] < n:
                if not cond.wait(10.0):
                    raise SystemExit(f"only {got[0]} of {n} answers")
    print((time.perf_counter() - t0) / steps, flush=True)
"""


def bare_round_trip(env: dict, participants: int, steps: int = 2000) -> float:
    """Wall seconds per Step published → `participants` StepDones received, on the bus alone."""
    with ProcessGroup(env) as group:
        start_participants(group, participants)
        bare = group.start([sys.executable, "-c", BARE, str(participants), str(steps)],
                           name="bare")
        bare.wait(900)
        if not bare.stdout:
            raise RuntimeError("the bare round trip printed nothing: " + " / ".join(bare.stderr[-5:]))
        return float(bare.stdout[-1])


def experiment(env: dict) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        one = Path(tmp) / "one"
        t0 = time.monotonic()
        with ProcessGroup(env) as group:
            group.start(mrta_argv("-q", "demo", "--duration", "60", "--speed", "0", "--fail",
                                  "robot2@30", "--no-live", "--output", one), name="one").wait(600)
        single = time.monotonic() - t0
        f = Path(tmp) / "exp.yaml"
        f.write_text("application: patrol\nduration: 60\nseeds: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n"
                     "failures: [none, robot2@30]\n")
        t0 = time.monotonic()
        with ProcessGroup(env) as group:
            run = group.start(mrta_argv("experiment", f, "--output", Path(tmp) / "out",
                                        "--jobs", "2"), name="experiment")
            run.wait(3600)
        total = time.monotonic() - t0
    return {"figure": "experiment_20_runs", "runs": 20, "jobs": 2, "wall_s": round(total, 1),
            "one_run_s": round(single, 1), "twenty_times_one_s": round(20 * single, 1),
            "speedup": round(20 * single / total, 2)}


FORGER = Path(__file__).resolve().parent.parent / "tests" / "procs" / "lockstep_forger.py"
ATTACKS = [("copy", []), ("replay", ["3"]), ("claims", ["4096", "0"]),
           ("claims", ["4000", "1024"]), ("descend", ["25"])]
if os.environ.get("MRTA_ATTACKS"):  # a subset: MRTA_ATTACKS=copy,descend
    ATTACKS = [a for a in ATTACKS if a[0] in os.environ["MRTA_ATTACKS"].split(",")]


def attack(env: dict, mode: str, args: list[str]) -> dict:
    """One forger against a fresh lockstep fleet; the agents' pauses before and during it."""
    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.lockstep.protocol import STATUS, LockstepStatus

    heard: dict[str, list[float]] = {"robot1": [], "robot2": []}
    forgiven = [0]
    with ProcessGroup(env) as group, open_bus(BusOptions(
            connect=[env["MRTA_RENDEZVOUS"]], listen=["tcp/127.0.0.1:0"])) as bus:
        for r in ("robot1", "robot2"):
            bus.subscribe(f"{r}/alliance/motivation/wander",
                          lambda s, r=r: heard[r].append(time.monotonic()))
        bus.subscribe(STATUS, lambda s: forgiven.__setitem__(0, s.message.forgiven),
                      msg_type=LockstepStatus)
        sim = group.start(mrta_argv("sim", "--world", "patrol", "--robot", "robot1", "--robot",
                                    "robot2", "--speed", "4", "--lockstep", "--wait-robots",
                                    "60"), name="sim")
        for r in ("robot1", "robot2"):
            group.start(mrta_argv("-q", "agent", r, "--robot-params",
                                  CONFIG / f"{r}_alliance_params.yaml", "--tasks-params",
                                  CONFIG / "tasks_alliance_params.yaml", "--layers-params",
                                  CONFIG / "layers_alliance_params.yaml", "--sim-time"), name=r)
        ready = sim.wait_stderr(lambda line: "ready:" in line, 120)
        run = _run_of(bus)
        time.sleep(10.0)
        start = time.monotonic()
        f = group.start([sys.executable, str(FORGER), mode, run, *args], name="forger")
        time.sleep(25.0)
        f.wait(60)
        end = time.monotonic()

    def longest(times, lo, hi):
        """The longest stretch of [lo, hi] without a sample (an agent that froze: all of it)."""
        inside = [lo, *(t for t in times if lo < t < hi), hi]
        return max(b - a for a, b in zip(inside, inside[1:]))

    return {"figure": "lockstep_attack", "forger": " ".join([mode, *args]),
            "ready": "lockstep with 2 participants" in ready,
            "longest_pause_s_before": round(max(longest(heard[r], start - 10, start)
                                                for r in heard), 2),
            "longest_pause_s_during": round(max(longest(heard[r], start, end)
                                                for r in heard), 2),
            "forgiveness_pauses": forgiven[0],
            "given_up": sum("no longer waited for" in line for line in sim.stderr)}


def _run_of(bus) -> str:
    """The run id from its barrier token."""
    from mrta_zenoh.lockstep.protocol import BARRIER

    found: list[str] = []
    watch = bus.watch_liveliness(f"{BARRIER}/*", lambda key, up: up and found.append(key))
    deadline = time.monotonic() + 10
    while not found and time.monotonic() < deadline:
        time.sleep(0.05)
    watch.close()
    return found[0].rsplit("/", 1)[-1]


def main() -> None:
    if len(sys.argv) > 2 and sys.argv[1] == "--child":
        child_participants(int(sys.argv[2]), int(sys.argv[3]))
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", choices=("patrol", "steps", "experiment", "attacks"))
    args = ap.parse_args()
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error")
    if args.only in (None, "patrol"):
        lock, free = patrol(env, True), patrol(env, False)
        print(json.dumps({"figure": "lockstep_patrol", "simulated_s": 300,
                          "rtf_lockstep": round(lock, 1), "rtf_without_lockstep": round(free, 1),
                          "ratio": round(lock / free, 2), "target_rtf_min": 30}), flush=True)
    if args.only in (None, "steps"):
        base = step_cost(env, 0, 200.0)
        for n in (10, 100):
            cost = step_cost(env, n, 40.0 if n == 100 else 100.0)
            bare = bare_round_trip(env, n)
            print(json.dumps({"figure": "lockstep_step_cost", "participants": n,
                              "ms_per_step": round(cost * 1e3, 3),
                              "ms_per_step_without_lockstep": round(base * 1e3, 3),
                              "lockstep_ms_per_step": round((cost - base) * 1e3, 3),
                              "bare_round_trip_ms": round(bare * 1e3, 3),
                              "barrier_ms_beyond_round_trip": round((cost - base - bare) * 1e3,
                                                                    3),
                              "target_ms_with_10": 1.0, "target_barrier_ms_with_100": 0.5}),
                  flush=True)
    if args.only in (None, "experiment"):
        print(json.dumps(experiment(env)), flush=True)
    if args.only in (None, "attacks"):
        for mode, extra in ATTACKS:
            print(json.dumps(attack(dict(env, MRTA_RENDEZVOUS=private_rendezvous()), mode,
                                    extra)), flush=True)


if __name__ == "__main__":
    main()
