"""A test peer: joins the bus with zero configuration, publishes typed messages under its name,
reports (as JSON lines) whose messages it received and which liveliness tokens came and went."""

import json
import sys
import threading
import time

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Header
from mrta_agent.alliance.messages import InterRobotCommunication

name = sys.argv[1]
duration = float(sys.argv[2]) if len(sys.argv) > 2 else 60.0
lock = threading.Lock()
seen: set[str] = set()


def out(obj):
    with lock:
        print(json.dumps(obj), flush=True)


def on_msg(sample):
    with lock:
        seen.add(sample.message.header.frame_id)


def on_token(key, alive):
    out({"event": "alive" if alive else "gone", "key": key, "t": time.time()})


with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
    bus.subscribe("test/*/irc", on_msg, msg_type=InterRobotCommunication)
    bus.watch_liveliness("test/*/alive", on_token)
    bus.declare_token(f"test/{name}/alive")
    out({"ready": name})
    seq = 0
    t_end = time.monotonic() + duration
    next_report = time.monotonic() + 0.3
    while not stop.is_set() and time.monotonic() < t_end:
        seq += 1
        bus.publish(f"test/{name}/irc",
                    InterRobotCommunication(Header(name, time.time(), seq), "wander", 10.0))
        if time.monotonic() >= next_report:
            with lock:
                got = sorted(seen)
                seen.clear()
            out({"name": name, "seen": got})
            next_report += 0.3
        stop.wait(0.05)
out({"exit": name})
