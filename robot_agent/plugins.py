"""The low level's plugin roles (dissertation §4.1): Sensor, SensoryEvaluator, Layer.

Like py_trees' `Behaviour.tick()`, the agent is a fixed driver and plugins fill in hooks:

    Sensor            setup(ctx) subscribes `<robot>/<topic_name>`; on_message(msg, now) keeps
                      the latest; is_up_to_date(now) uses the sensor's *own* timeout_duration.
    SensoryEvaluator  is_applicable(now) -> bool, once per high-level tick; published as
                      SensoryFeedback and fed to the behaviour set.
    Layer             on_activate(now), step(now, dt) at the control rate while its task is
                      active (read sensors, publish commands), on_deactivate(now).

Plugins are found by name through entry points — groups `mrta.alliance.sensors`,
`mrta.alliance.evaluators`, `mrta.alliance.layers` — so a pip-installed package can add its own,
as pluginlib did; or directly as `package.module:Class`.
"""

from __future__ import annotations

import importlib
import logging
import threading
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from typing import Any

import numpy as np

from mrta_zenoh import keys
from mrta_zenoh.bus import Bus
from mrta_zenoh.clock import Clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Message, Twist
from mrta_zenoh.yamlfile import did_you_mean

from .params import SensorParams

GROUPS = {
    "sensor": "mrta.alliance.sensors",
    "evaluator": "mrta.alliance.evaluators",
    "layer": "mrta.alliance.layers",
}


@dataclass
class AgentContext:
    """What plugins may use: the robot's id, the bus, the clock, its sensors and a seeded RNG."""

    robot_id: str
    bus: Bus
    clock: Clock
    rng: np.random.Generator
    sensors: dict[str, "Sensor"] = field(default_factory=dict)  # by topic_name
    layer_params: dict[str, Any] = field(default_factory=dict)
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("mrta.agent"))

    def publish_cmd(self, linear: float, angular: float) -> None:
        self.bus.publish(keys.cmd_vel(self.robot_id), Twist(float(linear), float(angular)))


class Sensor:
    message_type: type[Message] | None = None  # None: accept any type

    def __init__(self, params: SensorParams):
        self.params = params
        self.latest: Message | None = None
        self.latest_time: float | None = None
        self.received = 0
        self._lock = threading.Lock()
        self._sub = None

    def setup(self, ctx: AgentContext) -> None:
        key = keys.robot_topic(ctx.robot_id, self.params.topic_name)
        clock = ctx.clock

        def handler(sample):
            self.on_message(sample.message, clock.now())

        self._sub = ctx.bus.subscribe(key, handler, msg_type=self.message_type)

    def on_message(self, msg: Message, now: float) -> None:
        with self._lock:
            self.latest, self.latest_time = msg, now
            self.received += 1

    def is_up_to_date(self, now: float) -> bool:
        t = self.latest_time
        return t is not None and now - t <= self.params.timeout_duration


class SensoryEvaluator:
    def __init__(self, task_id: str, sensors: list[Sensor], ctx: AgentContext):
        self.task_id = task_id
        self.sensors = sensors
        self.ctx = ctx

    def is_applicable(self, now: float) -> bool:
        raise NotImplementedError


class Layer:
    params_section: str = ""  # the section of the layers file this layer reads, if any

    def __init__(self, ctx: AgentContext):
        self.ctx = ctx
        self.params: dict[str, Any] = dict(ctx.layer_params.get(self.params_section, {}) or {}) \
            if self.params_section else {}

    def on_activate(self, now: float) -> None:
        pass

    def step(self, now: float, dt: float) -> None:
        raise NotImplementedError

    def on_deactivate(self, now: float) -> None:
        self.ctx.publish_cmd(0.0, 0.0)


def known_plugins(kind: str) -> list[str]:
    return sorted(ep.name for ep in entry_points(group=GROUPS[kind]))


def load_plugin(kind: str, name: str, where: str = "") -> type:
    """The class for a plugin name (entry point or `module:Class`); ConfigError lists known ones."""
    base = {"sensor": Sensor, "evaluator": SensoryEvaluator, "layer": Layer}[kind]
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            cls = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise ConfigError(f"cannot load {kind} plugin {name!r}: {exc}", file=where or None) from None
    else:
        eps = {ep.name: ep for ep in entry_points(group=GROUPS[kind])}
        ep = eps.get(name)
        if ep is None:
            raise ConfigError(
                f"unknown {kind} plugin {name!r}{did_you_mean(name, eps)}; known: "
                f"{', '.join(sorted(eps)) or 'none'} (or give package.module:Class)",
                file=where or None)
        cls = ep.load()
    if not (isinstance(cls, type) and issubclass(cls, base)):
        raise ConfigError(f"{kind} plugin {name!r} is not a {base.__name__} subclass", file=where or None)
    return cls
