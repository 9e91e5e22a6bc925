"""One layer and one evaluator, written against mrta_agent.runtime.plugins as any plugin is."""

import msgspec

from mrta_zenoh.messages import Finite, Header
from mrta_agent.runtime.plugins import Layer, SensoryEvaluator

from .messages import Ping


class AnnounceParams(msgspec.Struct, forbid_unknown_fields=True):
    every: Finite = 0.5  # seconds between two pings


class Announce(Layer):
    """While its task is active: a Ping on `<robot>/ping` every `Announce/every` seconds."""

    params_section = "Announce"
    Params = AnnounceParams

    def on_activate(self, now: float) -> None:
        self.count = 0
        self.last = None

    def step(self, now: float, dt: float) -> None:
        if self.last is None or now - self.last >= self.params.every:
            self.last = now
            self.count += 1
            self.ctx.bus.publish(f"{self.ctx.robot_id}/ping",
                                 Ping(Header(self.ctx.robot_id, now, self.count), self.count))


class Always(SensoryEvaluator):
    """Always applicable: this task needs no sensor."""

    def is_applicable(self, now: float) -> bool:
        return True
