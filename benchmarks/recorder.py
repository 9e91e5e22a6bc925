"""Recorder benchmark: does `mrta record` keep up with the simulator's output?

Prints one JSON line per figure (robots = 10 and 1,000): samples the simulator published (its
clock, and sonar + odom + ground truth per robot at 10 Hz, the bumper on change and once a
simulated second) in a fixed simulated time at
`--speed 0`, samples the recorder wrote (read back from the file), the recorder's rate, and the
samples it did not write. Baseline in the same run: a raw zenoh-python subscriber counting the
same samples without converting or writing anything.

First, the conversion every recorded sample goes through (`viewer_json`: samples per second
to the JSON viewers get, beside msgspec's plain JSON of the same message).

Run: python benchmarks/recorder.py
"""

from __future__ import annotations

import json
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402
from mrta_zenoh.processes import ProcessGroup, mrta_argv  # noqa: E402


def child_count() -> None:
    from mrta_zenoh.bus import BusOptions
    from mrta_zenoh.bus.zenoh_bus import open_session
    from mrta_zenoh.lifecycle import stop_on_signals

    n = [0]
    with stop_on_signals() as stop:
        s = open_session(BusOptions())
        sub = s.declare_subscriber("**", lambda smp: n.__setitem__(0, n[0] + 1))
        tok = s.liveliness().declare_token("@mrta/bench/counter")
        print("ready", flush=True)
        stop.wait()
        print(json.dumps({"count": n[0]}), flush=True)
        tok.undeclare()
        sub.undeclare()
        s.close()


def run(env: dict, robots: int, seconds: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp, ProcessGroup(env) as group:
        out = Path(tmp) / "run.mcap"
        rec = group.start(mrta_argv("record", "-o", out), name="record")
        rec.wait_stderr(lambda line: "recording" in line, 60)
        counter = group.start([sys.executable, HERE, "--child"], name="counter")
        counter.wait_line(lambda line: line == "ready", 60)
        time.sleep(1.0)
        robot_args = []
        side = int(robots ** 0.5) + 1
        for i in range(robots):
            robot_args += ["--robot", f"r{i}={(i % side) * 3.0 - 40},{(i // side) * 3.0 - 40},0"]
        world = Path(tmp) / "arena.yaml"
        world.write_text("name: arena\nwalls:\n  - polygon: [[-45, -45], [200, -45], [200, 200], "
                         "[-45, 200]]\n")
        t0 = time.monotonic()
        sim = group.start(mrta_argv("sim", "--world", world, *robot_args, "--speed", "0",
                                    "--duration", str(seconds)), name="sim")
        sim.wait(1800)
        wall = time.monotonic() - t0
        time.sleep(3.0)
        group.stop_all()
        baseline = json.loads(counter.stdout[-1])["count"]
        from mrta_zenoh.recording import read_recording
        written = sum(1 for k, *_ in read_recording(out) if not k.startswith("@"))
        return {"figure": "recorder", "robots": robots, "simulated_s": seconds,
                "written": written, "baseline_received": baseline,
                "dropped_vs_baseline": baseline - written, "wall_s": round(wall, 1),
                "written_per_s": round(written / wall), "target": "none dropped at 10 robots"}


def conversion(n: int = 100_000) -> list[dict]:
    """What viewers get of a sample (mrta_zenoh.recording.json_channel: JSON, the header stamp
    as ROS time), per second, beside msgspec's plain JSON of the same message as the baseline
    (what the recorder wrote before the stamp became {sec, nsec})."""
    import msgspec

    from mrta_zenoh import codec
    from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
    from mrta_zenoh.recording import json_channel
    out = []
    for msg in (Odometry(Header("robot1", 12.34, 5), Pose2D(1.0, 2.0, 0.5), Twist(0.3, 0.1)),
                PointCloud(Header("robot1", 12.34, 5),
                           tuple(Point2D(0.1 * i, 0.2) for i in range(16)))):
        enc = codec.encoding_for(msg.TYPE_NAME)
        payload = codec.encode(msg)
        _, viewer = json_channel(enc)
        _, decode = codec.decoder_for(enc)
        rates = {}
        for name, convert in (("baseline", lambda b: msgspec.json.encode(decode(b))),
                              ("viewer", viewer)):
            t = time.perf_counter()
            for _ in range(n):
                convert(payload)
            rates[name] = round(n / (time.perf_counter() - t))
        out.append({"figure": "viewer_json", "type": msg.TYPE_NAME,
                    "samples_per_s": rates["viewer"], "baseline_per_s": rates["baseline"]})
    return out


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child_count()
        return
    for line in conversion():
        print(json.dumps(line), flush=True)
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), RUST_LOG="error")
    print(json.dumps(run(env, 10, 120.0)), flush=True)
    print(json.dumps(run(env, 1000, 5.0)), flush=True)


if __name__ == "__main__":
    main()
