"""A forger on the fleet's bus (issue 23): publishes what an attacker on an open bus would, with
raw zenoh-python and msgpack (no mrta code on the send path), once a subscriber is there.

argv: MODE RUN [N]
  step   RUN      one Step of the real run, stamp 1e9, step number 10**9
  ghost  RUN      one StepDone from `ghost` (no token) claiming 10**9 samples of robot1/cmd_vel
  creep  RUN N    N clock samples carrying the real run id, each 9.9 s ahead of the last, every
                  5 ms (the probe: 300 in 1.5 s), starting 9.9 s ahead of the latest real one
Prints {"ready": true} and then {"done": n}."""

import json
import sys
import threading
import time

import msgpack
import zenoh

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session

mode, run = sys.argv[1], sys.argv[2]
count = int(sys.argv[3]) if len(sys.argv) > 3 else 1
ENC = "application/msgpack;"
session = open_session(BusOptions())


def publisher(key):
    pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        status = pub.matching_status
        if getattr(status, "matching", status) is True:
            break
        time.sleep(0.02)
    time.sleep(0.2)
    return pub


try:
    print(json.dumps({"ready": True}), flush=True)
    if mode == "step":
        pub = publisher("@mrta/lockstep/step")
        pub.put(msgpack.packb({"stamp": 1e9, "step": 10**9, "counts": b"", "run": run,
                               "timeout": 2.5}), encoding=zenoh.Encoding(ENC + "mrta_msgs/Step"))
    elif mode == "ghost":
        pub = publisher("@mrta/lockstep/done/ghost")
        pub.put(msgpack.packb({"participant": "ghost", "stamp": 0.0,
                               "sent": {"robot1/cmd_vel": 10**9}, "next": -1.0, "run": run}),
                encoding=zenoh.Encoding(ENC + "mrta_msgs/StepDone"))
    elif mode == "creep":
        latest = [0.0]
        heard = threading.Event()

        def on_clock(sample):
            stamp = msgpack.unpackb(sample.payload.to_bytes())["stamp"]
            latest[0] = max(latest[0], stamp)
            heard.set()
        sub = session.declare_subscriber("clock", on_clock)
        heard.wait(30)
        sub.undeclare()
        pub = publisher("clock")
        stamp = latest[0]
        for _ in range(count):
            stamp += 9.9
            pub.put(msgpack.packb({"stamp": stamp, "source": run}),
                    encoding=zenoh.Encoding(ENC + "rosgraph_msgs/Clock"))
            time.sleep(0.005)
        print(json.dumps({"forged_to": stamp, "from": latest[0]}), flush=True)
    time.sleep(0.5)
    print(json.dumps({"done": count}), flush=True)
finally:
    session.close()
