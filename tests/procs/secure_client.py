"""A process with a given Zenoh config: `pub KEY` publishes 10 Twists and holds a token under
KEY; `watch SECONDS` prints every sample and liveliness change it sees as JSON lines."""

import json
import sys
import threading
import time
from pathlib import Path

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.messages import Twist

config, verb, arg = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
lock = threading.Lock()


def out(obj) -> None:
    """One whole line at a time: samples and liveliness changes arrive on different threads,
    and print() writes the text and its newline separately."""
    with lock:
        print(json.dumps(obj), flush=True)


with open_bus(BusOptions(zenoh_config=config)) as bus:
    if verb == "pub":
        token = bus.declare_token(f"{arg}/token")
        for i in range(10):
            bus.publish(arg, Twist(float(i), 0.0))
            time.sleep(0.05)
        time.sleep(0.5)
        out({"published": arg})
    else:
        bus.subscribe("**", lambda s: out({"sample": s.key}))
        bus.watch_liveliness("**", lambda k, a: out({"token": k, "alive": a}))
        out({"ready": True})
        time.sleep(float(arg))
