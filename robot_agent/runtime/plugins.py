"""The low level's plugin roles (dissertation §4.1): Sensor, SensoryEvaluator, Layer.

The agent is a fixed driver and plugins fill in hooks, with py_trees' life cycle:

    __init__(params)    cheap: keep the typed parameters, touch nothing else
    setup(ctx)          once, before the agent says it is ready: subscribe here (self.subscribe)
    ── per tick ──
    Sensor              on_message(msg, now) keeps the latest; is_up_to_date(now) uses the
                        sensor's *own* timeout_duration
    SensoryEvaluator    is_applicable(now) -> bool, once per high-level tick
    Layer               on_activate(now) (py_trees' initialise), step(now, dt) at the control
                        rate while its task is active (update), done(now) (SUCCESS: the
                        robot finished it), on_deactivate(now) (terminate)
    ──
    shutdown()          once: every subscription opened through self.subscribe is closed

Parameters are typed: a plugin lists the sections of the layers file it reads and the msgspec
Struct each must fit (`sections`). They are checked when the parameter files load, so a bad
value exits 2 naming file, line and key before the bus opens, instead of crashing when a layer
first runs; plugins read attributes, never re-parse strings per tick.

Plugins are found by name through entry points — groups `mrta.plugins.sensors`,
`mrta.plugins.evaluators`, `mrta.plugins.layers`, read by every architecture; the names they had
while only ALLIANCE read them, `mrta.alliance.*`, are still read — so a pip-installed package can
add its own,
as pluginlib did; or directly as `package.module:Class`. Old names (the reference files'
`alliance_test/*`) are aliases a package declares in `mrta.plugins.aliases` (or `mrta.alliance.aliases`) (a dict
old name → registered name), resolved here and nowhere else.
"""

from __future__ import annotations

import importlib
import logging
import threading
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Mapping, Sequence, TypeVar

import msgspec

from mrta_zenoh import instances, keys
from mrta_zenoh.architectures import Architecture
from mrta_zenoh.bus import Bus, LivelinessWatch, Subscription
from mrta_zenoh.clock import Clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.installed import entry_points
from mrta_zenoh.messages import Message, Twist
from mrta_zenoh.seeds import prepare
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean

from .instance import KEY as INSTANCE_KEY
from .instance import read_instance
from .params import EvaluatorSpec, SensorParams, TaskParams

if TYPE_CHECKING:
    import numpy as np  # annotations only: numpy loads when a plugin draws (mrta_zenoh.seeds)

T = TypeVar("T")

GROUPS = {
    "sensor": "mrta.plugins.sensors",
    "evaluator": "mrta.plugins.evaluators",
    "layer": "mrta.plugins.layers",
}
ALIASES_GROUP = "mrta.plugins.aliases"
LEGACY_PREFIX = ("mrta.plugins.", "mrta.alliance.")  # third-party packages may still use these


def plugin_entry_points(group: str) -> dict:
    """The entry points of `group` under its name and its legacy `mrta.alliance.*` name (the
    current name wins when a plugin is registered under both). Read once per import path
    (mrta_zenoh.installed): a robot loads one evaluator per task."""
    legacy = entry_points(group.replace(*LEGACY_PREFIX))
    return {**{ep.name: ep for ep in legacy}, **{ep.name: ep for ep in entry_points(group)}}


class NoParams(msgspec.Struct, forbid_unknown_fields=True):
    """The parameters of a plugin that reads none."""


@dataclass
class AgentContext:
    """What plugins may use: the robot's id, the bus, the clock, its sensors, a seeded RNG, the
    typed sections of the layers file, and a blackboard its plugins share (`share`)."""

    robot_id: str
    bus: Bus
    clock: Clock
    rng: np.random.Generator
    sensors: dict[str, "Sensor"] = field(default_factory=dict)  # by topic_name
    sections: dict[tuple[str, type], Any] = field(default_factory=dict)
    log: logging.Logger = field(default_factory=lambda: logging.getLogger("mrta.agent"))
    # the architecture the robot runs (mrta_zenoh.architectures): what a plugin may ask of it
    # (its "who is doing what" feed, its agent tokens) without naming it
    architecture: Architecture | None = None
    # the robot's instance document (runtime.instance: the file its layers file names, read
    # once), for the plugins that declare `instance_type`; None: it names none
    instance: Any = None
    # the robot's blackboard: what several of its plugins share (delivery's board of tasks
    # done, its path map), under a key the plugins' package owns; read and made with share()
    shared: dict[str, Any] = field(default_factory=dict)
    # what plugins refused of what they heard (delivery's board: a teammate's `done` it does not
    # believe): each a callable giving (kind, sender, reason, forged) → count, which the agent
    # says in its refusal tally with its logic's (runtime.loop.Agent.tell_refusals)
    refusal_sources: list[Callable[[], Mapping[tuple[str, str, str, bool], int]]] = field(
        default_factory=list)

    def share(self, key: str, make: Callable[[], T]) -> T:
        """The blackboard's value under `key`, made by `make()` by the first plugin to ask
        (plugins are set up one after the other, on one thread)."""
        if key not in self.shared:
            self.shared[key] = make()
        return self.shared[key]

    def publish_cmd(self, linear: float, angular: float) -> None:
        self.bus.publish(keys.cmd_vel(self.robot_id),
                         Twist(linear=float(linear), angular=float(angular)))

    def section(self, name: str, kind: type) -> Any:
        """The layers file's section `name` as `kind` (checked at load; defaults if absent)."""
        value = self.sections.get((name, kind))
        if value is None:
            value = self.sections[(name, kind)] = msgspec.convert({}, kind)
        return value


class Plugin:
    """What the three roles share: declared parameter sections and tracked subscriptions."""

    # layers-file section → the Struct it must fit; read with ctx.section(name, kind)
    sections: ClassVar[dict[str, type]] = {}
    # True: it draws from ctx.rng. The robot's stream (and numpy, ≈ 35 ms and 14 MB) is then
    # made when the plugins are set up, before the run's first step, not at the first draw
    # inside a tick: 100 lockstep agents importing numpy in their first simulated second run
    # that second at 0.22× real time, and a real robot's first command would wait
    # for the import. A plugin that never draws leaves numpy unloaded.
    draws: ClassVar[bool] = False
    # the instance document this plugin reads (ctx.instance), e.g. delivery's InstanceDoc: the
    # robot is refused at load when its layers file names no instance of this type
    instance_type: ClassVar[type | None] = None

    def __init__(self) -> None:
        self._subscriptions: list[Subscription | LivelinessWatch] = []
        self.ctx: AgentContext | None = None

    def setup(self, ctx: AgentContext) -> None:
        self.ctx = ctx

    def subscribe(self, key_expr: str, handler, **kwargs) -> Subscription:
        """ctx.bus.subscribe, remembered so shutdown() closes it."""
        sub = self.ctx.bus.subscribe(key_expr, handler, **kwargs)
        self._subscriptions.append(sub)
        return sub

    def watch_liveliness(self, key_expr: str, on_change: Callable[[str, bool], None],
                         **kwargs) -> LivelinessWatch:
        """ctx.bus.watch_liveliness, remembered so shutdown() closes it."""
        watch = self.ctx.bus.watch_liveliness(key_expr, on_change, **kwargs)
        self._subscriptions.append(watch)
        return watch

    def shutdown(self) -> None:
        for sub in self._subscriptions:
            sub.close()
        self._subscriptions.clear()


def heard_at(clock: Clock, msg: Message) -> float:
    """When a sample counts as heard. In lockstep, simulated time is shared: the sample's own
    stamp is exact, whatever step the participant's clock shows when it arrives; otherwise,
    the clock's time of arrival."""
    header = getattr(msg, "header", None)  # a sensor may take any type (Sensor.message_type)
    if header is not None and clock.in_lockstep():
        return header.stamp
    return clock.now()


class Sensor(Plugin):
    message_type: type[Message] | None = None  # None: accept any type

    def __init__(self, params: SensorParams):
        super().__init__()
        self.params = params
        self.latest: Message | None = None
        self.latest_time: float | None = None
        self.received = 0
        self._lock = threading.Lock()

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        clock = ctx.clock

        def handler(sample):
            self.on_message(sample.message, heard_at(clock, sample.message))

        self.subscribe(keys.robot_topic(ctx.robot_id, self.params.topic_name), handler,
                       msg_type=self.message_type)

    def on_message(self, msg: Message, now: float) -> None:
        with self._lock:
            self.latest, self.latest_time = msg, now
            self.received += 1

    def forget(self) -> None:
        """Drop the latest sample (time restarted: it belongs to another run)."""
        with self._lock:
            self.latest, self.latest_time = None, None

    def is_up_to_date(self, now: float) -> bool:
        t = self.latest_time
        return t is not None and now - t <= self.params.timeout_duration


class SensoryEvaluator(Plugin):
    def __init__(self, task_id: str, sensors: list[Sensor]):
        super().__init__()
        self.task_id = task_id
        self.sensors = sensors

    def is_applicable(self, now: float) -> bool:
        raise NotImplementedError

    # whether a task submitted at run time may be served with this evaluator and the layers
    # of the task it judges (Plugins.grow): the application's tasks are all of one kind
    # (delivery's point tasks); False: none is served at run time
    serves_submitted: ClassVar[bool] = False

    def withdrawn(self, now: float) -> bool:
        """Whether the task was withdrawn for good by `now` (cancelled at run time,
        mrta_zenoh.tasks): a robot serving a route then leaves it rather than wait for it
        (mrta_agent.route.executor). No task is withdrawn by default."""
        return False


class Layer(Plugin):
    """A task's behaviour. `params` is the typed section `params_section` (Params); `task_id`
    is the task it serves (set by the loader: a layer serving a point task — delivery — must
    know which one, while one class serves every task)."""

    params_section: ClassVar[str] = ""
    Params: ClassVar[type] = NoParams

    def __init__(self) -> None:
        super().__init__()
        self.params: Any = None
        self.task_id: str | None = None

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        self.params = ctx.section(self.params_section, self.Params) if self.params_section \
            else self.Params()

    @classmethod
    def declared_sections(cls) -> dict[str, type]:
        out = dict(cls.sections)
        if cls.params_section:
            out[cls.params_section] = cls.Params
        return out

    def on_activate(self, now: float) -> None:
        pass

    def step(self, now: float, dt: float) -> None:
        raise NotImplementedError

    def done(self, now: float) -> bool:
        """Whether this robot has finished the task since its last activation (py_trees'
        SUCCESS): what a robot serving a route of tasks moves on at
        (mrta_agent.route.executor). Default: never — a continuous task (patrol's) is not
        finished by running it."""
        return False

    def on_deactivate(self, now: float) -> None:
        self.ctx.publish_cmd(0.0, 0.0)


def declared_sections(cls: type) -> dict[str, type]:
    return cls.declared_sections() if issubclass(cls, Layer) else dict(cls.sections)


# ------------------------------------------------------------------------- finding plugins

def aliases() -> dict[str, str]:
    """Old plugin name → registered name, from every package's `mrta.plugins.aliases`."""
    out: dict[str, str] = {}
    for ep in plugin_entry_points(ALIASES_GROUP).values():
        table = ep.load()
        if not isinstance(table, dict):
            raise ConfigError(f"alias entry point {ep.name!r} ({ep.value}) is not a dict")
        out.update(table)
    return out


def load_plugin(kind: str, name: str, where: str = "") -> type:
    """The class for a plugin name (entry point, alias or `module:Class`); ConfigError naming
    `where` (file:line) and the known names otherwise."""
    base = {"sensor": Sensor, "evaluator": SensoryEvaluator, "layer": Layer}[kind]
    where = where or None
    if ":" in name:
        module, _, attr = name.partition(":")
        try:
            cls = getattr(importlib.import_module(module), attr)
        except (ImportError, AttributeError) as exc:
            raise ConfigError(f"cannot load {kind} plugin {name!r}: {exc}", file=where) from None
    else:
        eps = plugin_entry_points(GROUPS[kind])
        # a registered name needs no aliases: reading them loads every package that declares
        # some (a delivery robot loaded patrol's layers and ledger), once per plugin
        ep = eps.get(name)
        alias = {} if ep is not None else \
            {old: new for old, new in aliases().items() if new in eps}
        ep = ep or eps.get(alias.get(name, ""))
        if ep is None:
            known = sorted(eps) + sorted(alias)
            raise ConfigError(
                f"unknown {kind} plugin {name!r}{did_you_mean(name, known)}; known: "
                f"{', '.join(known) or 'none'} (or give package.module:Class)", file=where)
        cls = ep.load()
    if not (isinstance(cls, type) and issubclass(cls, base)):
        raise ConfigError(f"{kind} plugin {name!r} is not a {base.__name__} subclass", file=where)
    return cls


class Plugins:
    """A robot's low-level plugins with their typed parameters, built before the bus opens so
    that a bad plugin name or parameter is bad input (exit 2, file and line) and nothing runs.

    Architecture-neutral: ALLIANCE builds it from behaviour sets, MURDOCH from its skills; both give sensors, one evaluator per task and each task's layers."""

    def __init__(self, sensors: Sequence[SensorParams], evaluators: Sequence[EvaluatorSpec],
                 tasks: dict[str, TaskParams], layers_doc: YamlDoc | None,
                 instance: instances.Loaded | None = None):
        """`instance`: the robot's instance when its architecture has read it already (an
        own-route robot plans on it); else the one the layers file names is read here."""
        self.sections: dict[tuple[str, type], Any] = {}
        self._doc = layers_doc
        self.instance = instance if instance is not None else read_instance(layers_doc)
        self.sensors: dict[str, Sensor] = {}
        for sp in sensors:
            cls = self._load("sensor", sp.plugin_name, sp.where)
            self.sensors[sp.topic_name] = cls(sp)
        self.evaluators: dict[str, SensoryEvaluator] = {}
        for ev in evaluators:
            cls = self._load("evaluator", ev.plugin_name, ev.where)
            self.evaluators[ev.task_id] = cls(ev.task_id, [self.sensors[t] for t in ev.topics])
        self.layers: dict[str, list[Layer]] = {}
        for ev in evaluators:
            task = tasks[ev.task_id]
            self.layers[ev.task_id] = [self._load("layer", name, where)()
                                       for name, where in zip(task.layers, task.where)]
            for layer in self.layers[ev.task_id]:
                layer.task_id = ev.task_id
        read = {name for name, _ in self.sections} | {INSTANCE_KEY}
        self.unread_sections = [n for n in (self._doc.data if self._doc else {}) if n not in read]
        if layers_doc is not None:  # a run (a file check without a layers file has no instance)
            self._check_instance(layers_doc)

    def _check_instance(self, layers_doc: YamlDoc) -> None:
        for plugin in self.all():
            kind = plugin.instance_type
            if kind is None:
                continue
            if self.instance is None:
                raise layers_doc.error((), f"{type(plugin).__name__} reads the robot's instance: "
                                       f"name its file with `{INSTANCE_KEY}: FILE` (relative "
                                       "to this file)")
            if not isinstance(self.instance.doc, kind):
                raise ConfigError(f"{type(plugin).__name__} reads a {kind.__name__} instance, "
                                  f"but {self.instance.path} is a {self.instance.kind.application!r} "
                                  "one", file=str(layers_doc.path))

    def unread_warnings(self) -> list[str]:
        """One warning per section of the layers file that none of these plugins reads."""
        return [self._doc.warning((name,), f"section {name!r} is read by none of this robot's "
                                  "plugins") for name in self.unread_sections]

    def _load(self, kind: str, name: str, where: str) -> type:
        cls = load_plugin(kind, name, where)
        for section, struct in declared_sections(cls).items():
            if (section, struct) not in self.sections:
                self.sections[(section, struct)] = (
                    self._doc.convert((section,), struct) if self._doc is not None
                    else msgspec.convert({}, struct))
        return cls

    def all(self) -> list[Plugin]:
        return [*self.sensors.values(), *self.evaluators.values(),
                *(layer for layers in self.layers.values() for layer in layers)]

    def setup(self, ctx: AgentContext) -> None:
        ctx.sensors = self.sensors
        ctx.sections = self.sections
        ctx.instance = self.instance.doc if self.instance is not None else None
        for plugin in self.all():
            plugin.setup(ctx)
        if any(plugin.draws for plugin in self.all()):
            prepare(ctx.rng)

    def grow(self, task_ids: Sequence[str], ctx: AgentContext) -> list[str]:
        """Plugins for tasks submitted at run time (runtime/growth.py), set up at once: each
        an evaluator of the class, reading the sensors, of the robot's first task whose
        evaluator `serves_submitted`, and layers of that task's classes. The tasks built
        ([] when no task of this robot's takes submitted ones: it serves none of them)."""
        template = next((t for t, ev in self.evaluators.items() if ev.serves_submitted), None)
        if template is None:
            return []
        first = self.evaluators[template]
        built = []
        for tid in task_ids:
            if tid in self.evaluators:
                continue
            evaluator = type(first)(tid, list(first.sensors))
            layers = [type(layer)() for layer in self.layers.get(template, ())]
            for layer in layers:
                layer.task_id = tid
            self.evaluators[tid], self.layers[tid] = evaluator, layers
            for plugin in (evaluator, *layers):
                plugin.setup(ctx)
            built.append(tid)
        return built

    def shutdown(self) -> None:
        for plugin in self.all():
            plugin.shutdown()
