"""A lockstep participant that computes for longer than the simulator's `--lockstep-timeout`: it
ticks at 10 Hz on its LockstepClock and, at simulated time AT, keeps its loop thread busy for
BUSY wall seconds before it answers (as CBBA's first decision over a burst of 200 tasks does on a
loaded machine). One JSON line when it is up, one when it has computed, one per simulated second.

    python busy_participant.py NAME AT BUSY UNTIL
"""

import json
import sys
import time

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.lockstep.participant import LockstepClock

name, at, busy, until = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
    clock = LockstepClock(name)
    with clock.join(bus):
        print(json.dumps({"ready": True}), flush=True)
        while not clock.started.wait(0.05):
            if stop.is_set():
                sys.exit(0)
        t, computed = clock.now(), False
        while not stop.is_set() and t < until:
            if not computed and t >= at - 1e-9:
                end = time.monotonic() + busy
                while time.monotonic() < end:  # the loop thread computes: it uses CPU time
                    pass
                computed = True
                print(json.dumps({"computed": busy, "at": t}), flush=True)
            t = round(t + 0.1, 6)
            if not clock.sleep_until(t, stop):
                break
            if abs(t - round(t)) < 1e-6:
                print(json.dumps({"time": clock.now()}), flush=True)
