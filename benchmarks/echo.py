"""`mrta echo` under a burst, beside `mrta record` (its baseline, in the same run).

A recording of N samples (odometry and 8-point sonar clouds of ten robots, 1 ms apart, then one
`bench/end` sample) is replayed as `mrta replay --speed 0` replays it (its plan and its publish
loop, mrta_zenoh.tools.replay) — as fast as the replayer publishes — while `mrta echo '**'`
(YAML, and `--json`; output into a file, as `mrta record` writes into one) and `mrta record`
listen on the same private rendezvous. The replayer keeps its session open until the listeners
are done: closing it right after the last put drops what Zenoh's queues still hold (16,040 of
20,001 samples reached a recorder alone on a loaded machine), which `mrta replay` answers with a
bounded linger (replay.DRAIN), not a wait for the listeners. Prints one JSON line
per listener: samples it received of those replayed (echo: samples printed; record: samples in
its file), what echo said it dropped, the rate — samples handled per wall second from the
start of the replay until the listener had handled the last one (echo: printed `bench/end`;
record: the replay's end, a lower bound of its rate) — and the CPU the listener spent per
sample replayed (its whole life, start-up included), which the machine's load disturbs less.

Run: python benchmarks/echo.py [--samples 20000]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh import codec  # noqa: E402
from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist  # noqa: E402
from mrta_zenoh.processes import mrta_argv  # noqa: E402
from mrta_zenoh.recording import McapRecorder, read_recording  # noqa: E402

sys.path.append(os.path.dirname(HERE))
from procstat import proc_stat  # noqa: E402  (benchmarks/procstat.py, beside this script)

ROBOTS = 10
END = "bench/end"
WAIT = 300.0  # s: the most a listener is given to print the last sample


def make_recording(path: Path, n: int) -> None:
    t = [1_000_000_000_000]

    def log_time() -> int:
        t[0] += 1_000_000  # 1 ms apart
        return t[0]

    with McapRecorder(path, log_time=log_time) as rec:
        for i in range(n + 1):
            rid = f"robot{i % ROBOTS + 1}"
            h = Header(rid, i * 0.001, i)
            if i == n:
                msg, key = Twist(0.0, 0.0), END
            elif i % 2:
                msg = Odometry(h, Pose2D(i * 0.01, -i * 0.01, 0.5), Twist(0.4, 0.1))
                key = f"{rid}/odom"
            else:
                msg = PointCloud(h, tuple(Point2D(0.1 * k, 1.0 + 0.01 * i) for k in range(8)))
                key = f"{rid}/sonar"
            rec.sample(key, codec.encoding_for(msg.TYPE_NAME), codec.encode(msg))


def child_replay(recording: str) -> None:
    """`mrta replay RECORDING --speed 0`, with the session kept open until SIGINT."""
    import threading

    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.lifecycle import stop_on_signals
    from mrta_zenoh.tools.replay import execute, plan_replay

    plan = plan_replay(read_recording(Path(recording)))
    with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
        time.sleep(2.0)  # the listeners met
        print(json.dumps({"sent": execute(plan, bus, 0.0, threading.Event())}), flush=True)
        stop.wait()


def printed(path: Path, json_mode: bool) -> tuple[int, bool]:
    """Samples of robots in an echo output file, and whether the end sample is there."""
    data = path.read_bytes()
    marker = b'{"key": "robot' if json_mode else b"--- robot"
    return data.count(marker), (END.encode() in data)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=20_000)
    ap.add_argument("--child-replay", metavar="RECORDING", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child_replay:
        return child_replay(args.child_replay)
    n = args.samples
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous())
    echoes = {"echo": False, "echo --json": True}
    with tempfile.TemporaryDirectory() as tmp:
        source, out = Path(tmp) / "burst.mcap", Path(tmp) / "recorded.mcap"
        make_recording(source, n)
        procs: dict[str, subprocess.Popen] = {}
        files = {name: Path(tmp) / f"{name.replace(' ', '')}.txt" for name in echoes}
        done_at: dict[str, float] = {}
        try:
            procs["record"] = subprocess.Popen(mrta_argv("record", "-o", out, "**"), env=env,
                                               stderr=subprocess.PIPE)
            for line in procs["record"].stderr:
                if b"recording" in line:
                    break
            for name, json_mode in echoes.items():
                with files[name].open("wb") as f:
                    procs[name] = subprocess.Popen(
                        mrta_argv("echo", "**", *(["--json"] if json_mode else [])), env=env,
                        stdout=f, stderr=subprocess.PIPE)
            time.sleep(3.0)  # every subscription declared and met (echo has no readiness token)
            start = time.monotonic()
            procs["replay"] = subprocess.Popen([sys.executable, HERE, "--child-replay", source],
                                               env=env, stdout=subprocess.PIPE)
            procs["replay"].stdout.readline()  # {"sent": N}: the last sample is out
            replayed = time.monotonic() - start
            while len(done_at) < len(echoes) and time.monotonic() - start < WAIT:
                for name, json_mode in echoes.items():
                    if name not in done_at and printed(files[name], json_mode)[1]:
                        done_at[name] = time.monotonic()
                time.sleep(0.05)
            time.sleep(2.0)  # the recorder's last samples
            cpu = {name: proc_stat(p.pid)[0] for name, p in procs.items()}
            errs = {}
            for name, p in procs.items():
                p.send_signal(signal.SIGINT)
                errs[name] = (p.communicate(timeout=60)[1] or b"").decode(errors="replace")
        finally:
            for p in procs.values():
                if p.poll() is None:
                    p.kill()
                    p.wait()
        recorded = sum(1 for key, *_ in read_recording(out) if key.startswith("robot"))
        print(json.dumps({"listener": "mrta record (baseline)", "replayed": n,
                          "received": recorded, "replay_seconds": round(replayed, 2),
                          "samples_per_s": round(recorded / replayed, 1),
                          "cpu_us_per_sample": round(cpu["record"] / n * 1e6, 1)}), flush=True)
        for name, json_mode in echoes.items():
            count, _ = printed(files[name], json_mode)
            said = [x for x in errs[name].splitlines() if "dropped" in x or "not printed" in x]
            seconds = done_at.get(name, time.monotonic()) - start
            print(json.dumps({
                "listener": f"mrta {name}", "replayed": n, "received": count,
                "printed_the_last": name in done_at, "seconds": round(seconds, 2),
                "samples_per_s": round(count / seconds, 1),
                "cpu_us_per_sample": round(cpu[name] / n * 1e6, 1), "says": said}), flush=True)


if __name__ == "__main__":
    main()
