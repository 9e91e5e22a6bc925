"""Record the bus to MCAP: `mrta record`'s api."""

from __future__ import annotations

import threading
from pathlib import Path

from ..bus import BusOptions, open_bus
from ..errors import ConfigError
from ..keys import RECORDER_TOKEN, validate_key_expr
from ..lifecycle import stop_on_signals
from ..recording import McapRecorder, log


def run_record(*, output: Path, key_exprs: list[str], bus_options: BusOptions,
               duration: float | None = None, stop: threading.Event | None = None) -> int:
    for k in key_exprs:
        validate_key_expr(k)
    folder = Path(output).resolve().parent
    if not folder.is_dir():
        raise ConfigError(f"folder {folder} does not exist", file=str(output))
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus:
        rec = McapRecorder(output)
        subs = [bus.subscribe_raw(k, lambda s: rec.sample(s.key, s.encoding, s.payload))
                for k in key_exprs]
        watch = bus.watch_liveliness("**", rec.liveliness)
        token = bus.declare_token(f"{RECORDER_TOKEN}/{bus.zid}")
        log.info("recording %s to %s", " ".join(key_exprs), output)
        try:
            stop.wait(duration)
        finally:
            token.close()
            for s in subs:
                s.close()
            watch.close()
            rec.close()
    log.info("wrote %d messages to %s", rec.count, output)
    return 0


