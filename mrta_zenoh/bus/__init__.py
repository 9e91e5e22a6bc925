"""The bus: one interface, an in-process implementation and the Zenoh one (imported lazily).

`open_bus(options)` is what tools call; importing this package does not load zenoh, so pure
logic and unit tests stay fast.
"""

from __future__ import annotations

from .base import Bus, LivelinessWatch, RawSample, Sample, Subscription, Token
from .counts import Counts
from .inproc import InProcBus, InProcNetwork
from .options import BusOptions, check_endpoint

__all__ = [
    "Bus", "BusOptions", "Counts", "InProcBus", "InProcNetwork", "LivelinessWatch", "RawSample",
    "Sample", "Subscription", "Token", "check_endpoint", "open_bus",
]


def open_bus(options: BusOptions | None = None) -> Bus:
    from .zenoh_bus import ZenohBus

    return ZenohBus(options or BusOptions())
