"""A third architecture that lives only in the tests: fixed assignment with a standby.

Each robot's parameter file names the task it does (`task`) and, optionally, one it stands by
for (`standby`). A robot says what it does on `robotN/fixed/doing` every `period` seconds; a
standby robot takes over its standby task when no teammate has said it is doing it for
`timeout` seconds, and gives it back when the owner speaks again. It plugs in through the
architecture contract only (entry points in fixed_arch-0.1.dist-info), which is what
tests/test_architecture_contract.py proves: `mrta demo --architecture fixed` runs the patrol
mission with no file outside tests/ changed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

from mrta_zenoh.architectures import Doing
from mrta_zenoh.clock import EPSILON
from mrta_zenoh.messages import Header, Message, message
from mrta_agent.runtime.architecture import AgentArchitecture, Prepared
from mrta_agent.runtime.cli import agent_command
from mrta_agent.runtime.host import AgentOptions
from mrta_agent.runtime.coordinator import Coordinator, Say
from mrta_agent.runtime.params import (Doc, SensorParams, Sensors, load_layers_params,
                                       load_tasks_params, require_task, sensor_params)
from mrta_agent.runtime.plugins import EvaluatorSpec, Plugins
from mrta_zenoh import paramdoc
from mrta_zenoh.paramdoc import Id, Positive, Rate, Text


class FixedFile(Doc):
    """The robot file: a typed document (mrta_zenoh.paramdoc), as every architecture's."""

    task: Id
    sensors: Sensors
    name: Text = ""
    standby: Id = ""
    spin_rate: Rate = 10.0
    period: Positive = 0.5
    timeout: Positive = 2.0


@message("fixed_msgs/Doing")
class DoingMsg(Message):
    header: Header
    task_id: str


class FixedCoordinator(Coordinator):
    listens = ("doing",)

    def __init__(self, robot_id: str, task: str, standby: str | None, period: float,
                 timeout: float):
        self.robot_id, self.task, self.standby = robot_id, task, standby
        self.period, self.timeout = period, timeout
        self.heard: dict[str, float] = {}   # task → when a teammate last said it does it
        self.covering = False               # on the standby task
        self._last_said: float | None = None
        self._start: float | None = None

    @property
    def active_task(self) -> str | None:
        return self.standby if self.covering else self.task

    def teammate(self, robot: str, alive: bool) -> None:
        pass

    def hear(self, kind: str, sender: str, msg, at: float) -> bool:
        self.heard[msg.task_id] = max(self.heard.get(msg.task_id, at), at)
        return True

    def tick(self, now: float) -> Iterable[Say]:
        if self._start is None:
            self._start = now
        if self.standby is not None:
            last = self.heard.get(self.standby, self._start)
            self.covering = now - last > self.timeout + EPSILON
        if self._last_said is not None and now - self._last_said < self.period - EPSILON:
            return []
        self._last_said = now
        return [Say("doing", dict(task_id=self.active_task))]


class FixedArchitecture(AgentArchitecture):
    name = "fixed"
    title = "FIXED"
    namespace = "fixed"
    executable = "fixed/agent"
    command = "fixed"
    param_stem = "fixed"
    bound_formula = "timeout + period + 1 tick"
    messages = {"doing": DoingMsg}
    doing_kinds = ("doing",)

    def _read(self, path: Path) -> tuple[FixedFile, tuple[SensorParams, ...]]:
        d = paramdoc.load(path, FixedFile, "a fixed-assignment robot file")
        return d.value, sensor_params(d, d.value.sensors)

    def prepare(self, options: AgentOptions) -> Prepared:
        f, sensors = self._read(options.robot_params)
        task, standby, spin, period, timeout = (f.task, f.standby or None, f.spin_rate,
                                                f.period, f.timeout)
        tasks = load_tasks_params(options.tasks_params)
        mine = [t for t in (task, standby) if t is not None]
        for t in mine:
            require_task(t, tasks, options.robot_params, "task")
        evaluators = [EvaluatorSpec(t, "mrta/updated_sensory",
                                    tuple(s.topic_name for s in sensors)) for t in mine]
        plugins = Plugins(sensors, evaluators, tasks, load_layers_params(options.layers_params))
        params = (task, standby, period, timeout)
        return Prepared(options.robot_id, params, plugins, spin, 10.0,
                        f"fixed: {task}" + (f", standby for {standby}" if standby else ""),
                        plugins.unread_warnings())

    def coordinator(self, prepared: Prepared) -> FixedCoordinator:
        return FixedCoordinator(prepared.robot_id, *prepared.params)

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if isinstance(message, DoingMsg):
            return Doing(sender, message.task_id, True, message.header.stamp)
        return None

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """The owner's last word, then `timeout`, then the standby's next tick and its word."""
        f, _ = self._read(robot_params)
        return f.timeout + f.period + 1.0 / f.spin_rate


FIXED = FixedArchitecture()
agent = agent_command(FIXED, "Run ROBOT_ID's fixed-assignment agent (a test architecture).")
