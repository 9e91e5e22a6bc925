"""Record the bus to MCAP: `mrta record`'s api."""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path

from ..bus import BusOptions, open_bus
from ..errors import ConfigError
from ..keys import RECORDER_TOKEN, validate_key_expr
from ..lifecycle import stop_on_signals
from ..recording import McapRecorder, log


def run_record(*, output: Path, key_exprs: list[str], bus_options: BusOptions,
               duration: float | None = None, stop: threading.Event | None = None) -> int:
    """Write every sample on `key_exprs` (and every liveliness change) to `output` until
    `duration` wall seconds pass or `stop` is set; announce the recorder while it runs."""
    for k in key_exprs:
        validate_key_expr(k)
    folder = Path(output).resolve().parent
    if not folder.is_dir():
        raise ConfigError(f"folder {folder} does not exist", file=str(output))
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus, \
            contextlib.ExitStack() as handles:
        # closed in reverse: the token (no longer a recorder), the subscriptions, then the file
        rec = handles.enter_context(McapRecorder(output))
        for k in key_exprs:
            handles.enter_context(bus.subscribe_raw(
                k, lambda s: rec.sample(s.key, s.encoding, s.payload)))
        handles.enter_context(bus.watch_liveliness("**", rec.liveliness))
        handles.enter_context(bus.declare_token(f"{RECORDER_TOKEN}/{bus.zid}"))
        log.info("recording %s to %s", " ".join(key_exprs), output)
        stop.wait(duration)
    log.info("wrote %d messages to %s", rec.count, output)
    return 0


