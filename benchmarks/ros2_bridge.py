"""`mrta ros2 bridge` latency and throughput against a raw Zenoh relay of the same bytes, in
the same run.

Prints one JSON line per figure:
  twist_latency_us     our robotN/cmd_vel → the ROS 2 cmd_vel key (decode, convert, CDR,
                       attachment), median and p99 of sequential pings; baseline: a relay
                       process forwarding the same msgpack bytes, with an attachment, unchanged
  twist_throughput     messages/s received on the ROS 2 side while one publisher sends flat out
  sonar_latency_us     a 16-point sensor_msgs/PointCloud on the ROS 2 sonar key → our
                       robotN/sonar (CDR decode, convert, msgpack); baseline: the same CDR
                       bytes relayed raw
  sonar_throughput     messages/s received on our side

Run: python benchmarks/ros2_bridge.py [--pings 2000] [--n 20000]
Every party is its own process (router, bridge, relay) on a private loopback rendezvous, started
with subprocess before this process opens Zenoh.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import threading
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

from mrta_zenoh.bus.options import private_rendezvous  # noqa: E402

ROBOT = "bench"


def relay(in_key: str, out_key: str) -> None:
    """The baseline: every sample on in_key out again on out_key, bytes unchanged."""
    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.ros2.attachment import Stamper

    with open_bus(BusOptions()) as bus:
        pub = bus.declare_attached_publisher(out_key, lossy=False)
        stamper = Stamper()
        bus.subscribe_attached(in_key, lambda k, p, a: pub.put(p, stamper.next(time.time_ns())))
        bus.declare_token(f"relay_ready/{in_key.replace('/', '_')}")
        print("ready", flush=True)
        sys.stdin.readline()


def start(argv: list[str], env: dict) -> subprocess.Popen:
    return subprocess.Popen(argv, env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def wait_for(proc: subprocess.Popen, text: str, stream: str = "stderr") -> None:
    f = getattr(proc, stream)
    for line in f:
        if text in line:
            return
    raise RuntimeError(f"{proc.args}: ended before {text!r}")


class Probe:
    """Counts arrivals and wakes a waiting ping."""

    def __init__(self):
        self.count = 0
        self.event = threading.Event()

    def __call__(self, *args) -> None:
        self.count += 1
        self.event.set()


def latency(send, probe: Probe, pings: int) -> tuple[float, float]:
    out = []
    for _ in range(pings):
        probe.event.clear()
        t0 = time.perf_counter_ns()
        send()
        if not probe.event.wait(2.0):
            continue
        out.append((time.perf_counter_ns() - t0) / 1000)
    out.sort()
    return statistics.median(out), out[int(len(out) * 0.99) - 1]


def throughput(send, probe: Probe, n: int) -> float:
    start_count = probe.count
    t0 = time.perf_counter()
    for _ in range(n):
        send()
    deadline = time.perf_counter() + 10
    while probe.count - start_count < n and time.perf_counter() < deadline:
        time.sleep(0.001)
    return (probe.count - start_count) / (time.perf_counter() - t0)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--pings", type=int, default=2000)
    ap.add_argument("--n", type=int, default=20000)
    args = ap.parse_args()
    env = dict(os.environ, MRTA_RENDEZVOUS=private_rendezvous(), PYTHONUNBUFFERED="1",
               RUST_LOG="error")
    mrta = [sys.executable, "-m", "mrta_zenoh.cli.main"]
    procs = [start(mrta + ["router"], env)]
    try:
        wait_for(procs[0], "router listening")
        procs.append(start(mrta + ["ros2", "bridge", "--robot", ROBOT], env))
        wait_for(procs[-1], "ready: ROS 2")
        for pair in (("relay/cmd_vel", "relay_out/cmd_vel"), ("relay/sonar", "relay_out/sonar")):
            procs.append(start([sys.executable, __file__, "--relay", *pair], env))
            wait_for(procs[-1], "ready", "stdout")
        measure(args, env)
    finally:
        for p in procs:
            p.stdin.close()
            p.terminate()
        for p in procs:
            p.wait(10)
    return 0


def measure(args, env) -> None:
    os.environ.update(env)
    from mrta_zenoh import codec
    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.messages import Header, Point2D, PointCloud, Twist
    from mrta_zenoh.ros2 import names
    from mrta_zenoh.ros2.node import Ros2Node
    from mrta_zenoh.ros2.types import SONAR_TYPES, TWIST, Ros2Types

    types = Ros2Types()
    with open_bus(BusOptions()) as bus, Ros2Node(bus, types, name="bench_robot",
                                                 namespace="/" + ROBOT) as node:
        twist = Twist(0.3, -0.1)
        twist_bytes = codec.encode_struct(twist)
        cloud = PointCloud(Header("bench/sonar", 1.0, 0),
                           tuple(Point2D(0.1 * i, -0.05 * i) for i in range(16)))
        cloud_cdr = types.serialize(types.sonar_to_ros(cloud, "pointcloud"),
                                    SONAR_TYPES["pointcloud"])
        ros_cmd = names.topic_key(0, f"/{ROBOT}/cmd_vel", TWIST, types.hash(TWIST))
        via_bridge, via_relay = Probe(), Probe()
        bus.subscribe_attached(ros_cmd, via_bridge)
        bus.subscribe_attached("relay_out/cmd_vel", via_relay)
        sonar_bridge, sonar_relay = Probe(), Probe()
        bus.subscribe(f"{ROBOT}/sonar", sonar_bridge)
        bus.subscribe_attached("relay_out/sonar", sonar_relay)
        # KEEP_ALL: rmw_zenoh's publishers DROP under load unless RELIABLE + KEEP_ALL, and this
        # measures the bridge, not that rule
        sonar_pub = node.publisher("sonar", SONAR_TYPES["pointcloud"],
                                   names.Qos(names.RELIABLE, names.VOLATILE, names.KEEP_ALL, 10))
        relay_sonar = bus.declare_attached_publisher("relay/sonar", lossy=False)
        relay_att = b"\x01" + b"\x00" * 32
        time.sleep(2.0)  # declarations travel

        cases = {
            "twist": (lambda: bus.publish(f"{ROBOT}/cmd_vel", twist), via_bridge,
                      lambda: bus.publish_raw("relay/cmd_vel", "application/msgpack",
                                              twist_bytes), via_relay),
            "sonar": (lambda: sonar_pub.publish_cdr(cloud_cdr), sonar_bridge,
                      lambda: relay_sonar.put(cloud_cdr, relay_att), sonar_relay),
        }
        for kind, (ours, ours_probe, raw, raw_probe) in cases.items():
            for _ in range(3):  # warm up both paths
                latency(ours, ours_probe, 50)
                latency(raw, raw_probe, 50)
            lo = latency(ours, ours_probe, args.pings)
            lr = latency(raw, raw_probe, args.pings)
            print(json.dumps({"figure": f"{kind}_latency_us", "bridge_median": round(lo[0], 1),
                              "bridge_p99": round(lo[1], 1), "relay_median": round(lr[0], 1),
                              "relay_p99": round(lr[1], 1),
                              "ratio_median": round(lo[0] / lr[0], 2)}), flush=True)
            to = throughput(ours, ours_probe, args.n)
            time.sleep(0.5)
            tr = throughput(raw, raw_probe, args.n)
            print(json.dumps({"figure": f"{kind}_throughput_msgs_s", "bridge": round(to),
                              "relay": round(tr), "ratio": round(to / tr, 2)}), flush=True)
            time.sleep(0.5)


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--relay":
        relay(sys.argv[2], sys.argv[3])
    else:
        sys.exit(main())
