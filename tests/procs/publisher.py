"""Publishes a scripted sequence of samples: typed messages and, on request, malformed payloads
sent the way any Zenoh client in our wire format would (raw zenoh-python, no mrta code on the
send path for the 'raw' items)."""

import json
import sys
import time

import msgpack
import zenoh

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import open_session

# argv: KEY then items: "irc:<frame>:<task>", "garbage", "wrongtype", "rawirc:<frame>",
# "hex:<type name>:<payload in hex>"
key = sys.argv[1]
items = sys.argv[2:]
session = open_session(BusOptions())
try:
    pub = session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
    token = session.liveliness().declare_token(f"{key}/publisher_ready")
    print(json.dumps({"ready": True}), flush=True)
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:  # send only once a subscriber (the tool under test) is there
        status = pub.matching_status
        if getattr(status, "matching", status) is True:
            break
        time.sleep(0.02)
    time.sleep(0.1)
    for seq, item in enumerate(items):
        kind, _, rest = item.partition(":")
        if kind in ("irc", "rawirc"):
            frame, _, task = rest.partition(":")
            body = {"header": {"frame_id": frame, "stamp": time.time(), "seq": seq},
                    "task_id": task or "wander", "expected_duration": 12}  # int: other clients do
            pub.put(msgpack.packb(body),
                    encoding=zenoh.Encoding("application/msgpack;alliance_msgs/InterRobotCommunication"))
        elif kind == "garbage":
            pub.put(b"\xc1\xc1not msgpack",
                    encoding=zenoh.Encoding("application/msgpack;alliance_msgs/InterRobotCommunication"))
        elif kind == "missing":
            pub.put(msgpack.packb({"task_id": "x"}),
                    encoding=zenoh.Encoding("application/msgpack;alliance_msgs/InterRobotCommunication"))
        elif kind == "hex":
            type_name, _, payload = rest.rpartition(":")
            pub.put(bytes.fromhex(payload),
                    encoding=zenoh.Encoding(f"application/msgpack;{type_name}"))
        elif kind == "unknown":
            pub.put(msgpack.packb({"level": 3, "items": [1, 2]}),
                    encoding=zenoh.Encoding("application/msgpack;vendor_msgs/Battery"))
        time.sleep(0.05)
    time.sleep(0.5)
    print(json.dumps({"done": len(items)}), flush=True)
    token.undeclare()
    pub.undeclare()
finally:
    session.close()
