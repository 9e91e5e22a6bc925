"""Watches the `clock` key: prints one JSON line a second with the samples seen and the longest
wall-time gap between two of them so far (a stalled simulator shows as a long gap)."""

import json
import threading
import time

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Clock

state = {"count": 0, "last": None, "max_gap": 0.0, "stamp": 0.0}
lock = threading.Lock()


def on_clock(sample):
    now = time.monotonic()
    with lock:
        if state["last"] is not None:
            state["max_gap"] = max(state["max_gap"], now - state["last"])
        state["last"] = now
        state["count"] += 1
        state["stamp"] = sample.message.stamp


with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
    bus.subscribe("clock", on_clock, msg_type=Clock)
    bus.declare_token("@mrta/test/clock_gaps")
    print(json.dumps({"ready": True}), flush=True)
    while not stop.wait(1.0):
        with lock:
            print(json.dumps({k: state[k] for k in ("count", "max_gap", "stamp")}), flush=True)
