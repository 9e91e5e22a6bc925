"""A process with a given Zenoh config: `pub KEY` publishes 10 Twists and holds a token under
KEY; `watch SECONDS` prints every sample and liveliness change it sees as JSON lines."""

import json
import sys
import time
from pathlib import Path

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.messages import Twist

config, verb, arg = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
with open_bus(BusOptions(zenoh_config=config)) as bus:
    if verb == "pub":
        token = bus.declare_token(f"{arg}/token")
        for i in range(10):
            bus.publish(arg, Twist(float(i), 0.0))
            time.sleep(0.05)
        time.sleep(0.5)
        print(json.dumps({"published": arg}), flush=True)
    else:
        bus.subscribe("**", lambda s: print(json.dumps({"sample": s.key}), flush=True))
        bus.watch_liveliness("**", lambda k, a: print(json.dumps({"token": k, "alive": a}),
                                                      flush=True))
        print(json.dumps({"ready": True}), flush=True)
        time.sleep(float(arg))
