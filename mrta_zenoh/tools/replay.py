"""Republish a recording onto the bus with its original timing (rosbag play): `mrta replay`.

Bus channels go out on their keys with their Zenoh encodings, liveliness changes as tokens
declared and undeclared again, so `mrta supervise`, `mrta echo` and `mrta view` work on a past
run exactly as on a live one. The simulated clock is left out unless asked (`clock=True`): a
replay then runs on the wall clock of whoever watches, or on its own recorded time.

Timing follows the recording's log times (mrta_zenoh.recording): a wall-time recording (`mrta
record`) replays at the pace it was recorded; a simulated-time one (the mission runner's, `mrta
view --sim-time`) at the simulated pace — a 60 s mission recorded at `--speed 0` in 2 s replays
in 60 s at `--speed 1`, in 6 s at `--speed 10` — its simulator restarts 1 s apart.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from pathlib import Path

from ..bus import BusOptions, open_bus
from ..errors import ConfigError
from ..keys import CLOCK, LIVELINESS_PREFIX, matches, validate_key_expr
from ..lifecycle import stop_on_signals
from ..recording import read_recording

log = logging.getLogger("mrta.replay")


def run_replay(*, recording: Path, bus_options: BusOptions, speed: float = 1.0,
               key_expr: str = "**", clock: bool = False,
               stop: threading.Event | None = None) -> int:
    """Publish every recorded sample (matching `key_expr`) at its recorded pace × `speed`
    (0: as fast as possible); returns how many samples went out."""
    validate_key_expr(key_expr)
    if speed < 0:
        raise ConfigError(f"--speed must be ≥ 0, got {speed}")
    records = read_recording(recording)
    if not records:
        raise ConfigError("the recording holds no bus channel", file=str(recording))
    if records.log_time == "simulated":
        log.info("%s is in simulated time: replaying %.1f simulated s at %s× the simulated pace",
                 recording, (records[-1][2] - records[0][2]) / 1e9, speed or "∞")
    sent = 0
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus:
        tokens = {}
        time.sleep(0.5)  # subscribers already running are reached (discovery)
        t0, wall0 = records[0][2], time.monotonic()
        try:
            for key, encoding, t, payload in records:
                if stop.is_set():
                    break
                if speed > 0:
                    ahead = (t - t0) / 1e9 / speed - (time.monotonic() - wall0)
                    if ahead > 0 and stop.wait(ahead):
                        break
                if key.startswith(LIVELINESS_PREFIX):
                    token_key = key[len(LIVELINESS_PREFIX):]
                    if not matches(key_expr, token_key):
                        continue
                    alive = json.loads(payload).get("alive")
                    if alive and token_key not in tokens:
                        tokens[token_key] = bus.declare_token(token_key)
                    elif not alive and token_key in tokens:
                        tokens.pop(token_key).close()
                    continue
                if (key == CLOCK and not clock) or not matches(key_expr, key):
                    continue
                bus.publish_raw(key, encoding, payload)
                sent += 1
        finally:
            for tok in tokens.values():
                tok.close()
    log.info("replayed %d samples from %s", sent, recording)
    return sent
