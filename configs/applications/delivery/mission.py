"""The delivery mission as `mrta demo --application delivery` and `mrta experiment` run it:
registered under `mrta.missions` as `delivery`. The framework's runner launches, records,
supervises and writes the summary; this hook adds what only a delivery run can measure — the
allocation log and the metrics against the optimal assignment (metrics.py) — from the
recording. Every delivery package holds `launch/delivery_sim.launch`, its instance
(`config/instance.yaml`) and a layers file naming it; `derive` writes a run's own packages from
an instance file (`mrta demo --instance FILE`).

`metrics` lands in summary.json's `metrics` (scalars: also `mrta experiment`'s columns);
`sections` is the instance, the allocation log, the objectives and the overlaps, the top-level
`instance`, `allocation`, `objectives` and `overlaps` of summary.json: delivery's own schema
(`DeliverySections`, declared as the Mission's `summary_sections`), which `read_summary` checks
a summary against when it reads one back.

A run ends when nothing is left to serve (`ended_at`: every task's first completion, from the
robots' `done` events, or — under hard windows — when it was missed: metrics.done_at): the
runner learns it live through the task watch (`DeliveryWatch`: every task `done` or `missed`
for good) and stops the simulator; the figures cover the run up to `ended_at`.
"""

from __future__ import annotations

import functools
import threading
from pathlib import Path
from typing import Any

import msgspec

from mrta_agent.runtime.instance import named_instance
from mrta_agent.runtime.params import load_layers_params
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import first_chunk
from mrta_supervisor.mission.ground_truth import decisions
from mrta_supervisor.mission import Mission, MissionRun
from mrta_supervisor.mission.roles import as_struck
from mrta_supervisor.live.tasks import TaskStatus, TaskWatch
from mrta_supervisor.mission.summary import SummarySections

from .done_rule import DoneRule
from .generate import derive
from .instance import DeliveryParams, InstanceBody, InstanceDoc, load_document
from .keys import ALL_DONE, ALL_STARTED, Event
from .messages import TaskEvent
from .metrics import RunAnalysis, analyse, done_at, instance_json
from .runtime_tasks import accounting, changes, live_instance, submitted


class _Section(msgspec.Struct, forbid_unknown_fields=True):
    pass


class RobotEntry(_Section):
    id: str
    start: tuple[float, float]
    speed: float
    capabilities: list[str]


class TaskEntry(_Section):
    id: str
    position: tuple[float, float]
    arrival: float
    service: float
    capability: str


class LegacyInstance(_Section):
    """A schema-2 summary's instance (robots and tasks as lists), still read back."""

    robots: list[RobotEntry]
    tasks: list[TaskEntry]
    cost: list[list[float | None]]   # cost[i][j]: robot i's travel time to task j (None: cannot)
    cost_model: str


class AllocationEntry(_Section, omit_defaults=True):
    """One stretch a robot held a task (metrics.Entry); a summary written before stretches had
    an end and a reason reads (and writes back) without them."""

    task: str
    robot: str
    assigned_at: float
    started_at: float | None
    done_at: float | None
    reached_at: float | None = None
    ended_at: float | None = None       # None: a summary written before stretches ended
    reason: str = ""


class ReferenceEntry(_Section):
    value: float | None                 # None: none found, or none looked for (`why`)
    method: str
    proven_optimal: bool
    stopped_by_time_limit: bool
    routes: dict[str, list[str]]
    why: str = ""


class ObjectivesSection(_Section):
    """The objectives along the routes robots served, and their references (objectives.py)."""

    objective: str
    served: dict[str, list[str]]
    values: dict[str, float]
    complete: bool
    reference: dict[str, ReferenceEntry]
    optimality: float | None


class OverlapEntry(_Section):
    task: str
    robots: list[str]
    start: float = msgspec.field(name="from")
    end: float = msgspec.field(name="to")


class DeliverySections(SummarySections):
    """`instance` is the instance document (metrics.instance_json: fed back as `--instance` it
    gives the same run) with the cost matrix and its model; a schema-2 summary's lists are
    read too."""

    instance: dict[str, Any]
    allocation: list[AllocationEntry]
    objectives: ObjectivesSection | None = None
    overlaps: list[OverlapEntry] = []
    # what became of every task submitted or cancelled at run time (runtime_tasks.accounting)
    tasks_at_run_time: dict[str, Any] | None = None

    def __post_init__(self) -> None:
        try:
            msgspec.convert(self.instance, InstanceDoc)
        except msgspec.ValidationError as current:
            try:
                msgspec.convert(self.instance, LegacyInstance)
            except msgspec.ValidationError:
                raise ValueError(f"instance: {current}") from None


def run_instance(run: MissionRun) -> InstanceBody:
    """The instance the run's robots serve: the file its layers file names, read once however
    often the runner asks (the task watch, the end of the run, the analysis)."""
    layers = load_layers_params(run.layers_params)
    path = named_instance(layers)
    if path is None:
        raise ConfigError(f"{layers.path}: names no instance (`instance: FILE`): a delivery "
                          "run needs the instance its robots serve")
    stat = path.stat()
    return _read_instance(path.resolve(), stat.st_mtime_ns, stat.st_size)


def run_delivery(run: MissionRun) -> DeliveryParams:
    """The run's layers file's `Delivery` section (how near its robots stop at a task, the
    task watch's `miss_grace`), checked: a bad value is a ConfigError naming file, line, key."""
    layers = load_layers_params(run.layers_params)
    return DeliveryParams() if layers is None else layers.convert(("Delivery",), DeliveryParams)


def run_tolerance(run: MissionRun) -> float:
    """How near the run's robots stop at a task (its layers file's `Delivery` section)."""
    return run_delivery(run).tolerance


@functools.lru_cache(maxsize=4)
def _read_instance(path: Path, _mtime_ns: int, _size: int) -> InstanceBody:
    """An instance file's body, read once per version of the file (the cache key)."""
    return load_document(path).body()


class DeliveryWatch(TaskWatch):
    """A delivered task is done for good; one that arrives later is waiting until then. A
    `done` counts as the robots' boards count it (board.py, done_rule.py): on its sender's own
    key, after its own `started` a service before — forged ones do not end the run. (A task
    cancelled at run time is settled by the supervisor itself: Supervisor.on_change.)

    Under hard windows a task is missed for good (`lapsed`) once its due has passed by
    `grace` with no believed `started` — no robot may start it any more — or, started, once
    its service would have been over by `grace` without a `done` (its robot crashed or left
    it); the supervisor takes that word only for a task no robot holds. So a run in which a
    task is missed ends when nothing is left to serve, not at its duration. `grace`: the run's
    `Delivery.miss_grace` (DeliveryParams; 2 s by default: a `started` stamped by the due is
    heard well within it, and the supervisor also waits while a robot holds the task)."""

    served_in_turn = True  # more tasks than robots: a task may wait for a robot to be free

    def __init__(self, params: InstanceBody, grace: float = DeliveryParams().miss_grace):
        self.params = params
        self.grace = grace
        self.arrivals = {tid: t.arrival for tid, t in params.tasks.items()}
        self.rule = DoneRule(params, params.path_map())
        self._lock = threading.Lock()  # samples come on the bus's threads

    def feed(self):
        return [(ALL_DONE, TaskEvent), (ALL_STARTED, TaskEvent)]

    def schedule(self) -> list[TaskStatus]:
        return [TaskStatus(tid, "waiting", at) for tid, at in self.arrivals.items() if at > 0]

    def read(self, key: str, message) -> TaskStatus | None:
        sender = first_chunk(key)
        if message.event != key.rsplit("/", 1)[-1] or message.header.frame_id.strip("/") != sender:
            return None  # the board's rule (board.py): only a robot's own events count
        task, stamp = message.task_id, message.header.stamp
        with self._lock:
            if message.event == Event.STARTED:
                believed = self.rule.on_started(sender, task, stamp) is not None
            else:
                believed = self.rule.on_done(sender, task, stamp)
        return TaskStatus(task, "done") if believed else None

    def lapsed(self, elapsed: float) -> list[TaskStatus]:
        if self.params.windows != "hard":
            return []  # a soft due binds nothing: a task may still be served late
        with self._lock:
            started: dict[str, float] = {}
            for (_robot, task), stamp in self.rule.started.items():
                started[task] = min(stamp, started.get(task, stamp))
        out = []
        for tid, t in self.params.tasks.items():
            if t.due is None:
                continue
            over = t.due if tid not in started else max(t.due, started[tid]) + t.service
            if elapsed >= over + self.grace:
                out.append(TaskStatus(tid, "missed"))
        return out

    def servers(self, task: str) -> frozenset[str] | None:
        """The robots with the task's capability (a task waiting while all of them are busy
        is queued, not unattended)."""
        if task not in self.params.tasks:
            return None
        return frozenset(rid for rid in self.params.robots if self.params.capable(rid, task))


class Delivery(Mission):
    name = "delivery"
    title = "Delivery mission"
    launch = "delivery_sim.launch"
    summary_sections = DeliverySections
    # tasks served in turn: no `first_full_allocation` (its waiting and completion times —
    # mean_waiting_time, flowtime, makespan — say how fast tasks were taken up)
    instantaneous = False
    instances = True  # its packages are derived from instance files (derive), not made by the wizard
    better = {"makespan": "lower", "total_distance": "lower", "mean_waiting_time": "lower",
              "achieved_cost": "lower", "optimality": "higher", "ia_optimality": "higher",
              "completed": "higher", "assigned": "higher", "handovers": "lower",
              "overlaps": "lower", "objective_minsum": "lower", "objective_makespan": "lower",
              "objective_flowtime": "lower", "gini_served": "lower", "gini_busy": "lower",
              "gini_distance": "lower", "served_in_window": "higher", "gap_minsum": "lower",
              "gap_makespan": "lower", "gap_flowtime": "lower", "served_gap": "lower",
              "missed": "lower", "late": "lower", "lateness": "lower", "early": "lower"}

    # a point task held longer is served slower, and nobody holding it is also a task done:
    # of a task's coverage only two robots on it at once is worse (an overlap)
    coverage_better = {"more_than_one": "lower"}

    def __init__(self) -> None:
        self._last: tuple[int, RunAnalysis] | None = None

    def default_failure(self, robots: list[str], duration: float) -> str | None:
        """None: the delivery baseline is measured without faults (ask with --fail)."""
        return None

    def derive(self, instance: Path, folder: Path, architecture: str | None = None) -> None:
        """`mrta demo --instance FILE`: the packages derived from the file, into `folder` —
        every architecture's, or those a run under `architecture` reads."""
        derive(load_document(instance), folder, architecture)

    def instance_file(self, run: MissionRun) -> Path | None:
        """The file the run's layers file names (a run of `--instance` derives it)."""
        return named_instance(load_layers_params(run.layers_params))

    def ended_at(self, run: MissionRun, records: list) -> float | None:
        """When nothing was left to serve (metrics.done_at: every task completed, or missed
        under hard windows — None: some was neither by the duration); the tasks submitted at
        run time among them."""
        return done_at(records, live_instance(run_instance(run), submitted(changes(records))),
                       run_tolerance(run), run.options.duration)

    def analysis(self, run: MissionRun, records: list) -> RunAnalysis:
        """Computed once per recording (metrics and sections both read it)."""
        if self._last is not None and self._last[0] == id(records):
            return self._last[1]
        # what is still held at the end of the run ends there (simulated seconds)
        base = run_instance(run)
        seen = submitted(changes(records))  # tasks at run time (runtime_tasks.py)
        params = live_instance(base, seen)
        tolerance = run_tolerance(run)
        ended = done_at(records, params, tolerance, run.options.duration)
        end = run.options.duration if ended is None else min(ended, run.options.duration)
        made = decisions(records, run.arch, end)
        result = analyse(records, run.arch, params, end, as_struck(run.faults, records),
                         made.objective if made is not None and made.objective else None,
                         tolerance)
        result.base, result.submitted = base, seen
        if seen:
            result.runtime = accounting(seen, result.log, end)
            result.metrics.update({f"submitted_{k}": n
                                   for k, n in result.runtime["counts"].items()},
                                  submitted=len(result.runtime["tasks"]),
                                  served_after_cancel=len(result.runtime["served_after_cancel"]))
        self._last = (id(records), result)
        return result

    def metrics(self, run: MissionRun, records: list) -> dict[str, Any]:
        return self.analysis(run, records).metrics

    def sections(self, run: MissionRun, records: list) -> DeliverySections:
        a = self.analysis(run, records)
        from .objectives import overlaps
        instance = instance_json(a.base, a.base.problem())
        if a.submitted:  # what entered at run time: a run of this section replays it
            instance["submitted"] = msgspec.to_builtins(a.submitted)
        return msgspec.convert({"instance": instance, "tasks_at_run_time": a.runtime,
                                "allocation": [e.to_json() for e in a.log],
                                "objectives": a.objectives,
                                "overlaps": [o.to_json() for o in overlaps(a.log)]},
                               DeliverySections)

    def task_watch(self, run: MissionRun) -> TaskWatch:
        return DeliveryWatch(run_instance(run), run_delivery(run).miss_grace)

    def describe(self, metrics: dict[str, Any]) -> list[str]:
        name = metrics.get("objective", "minsum")
        value = metrics.get(f"objective_{name}")
        return [f"delivered {metrics['completed']}/{metrics['tasks']}; makespan "
                f"{metrics['makespan'] if metrics['makespan'] is not None else '—'} s; "
                f"{name} {value if value is not None else '—'} vs "
                f"{against_reference(metrics, name)}; overlaps {metrics.get('overlaps', 0)}"
                ] + arrival_lines(metrics) + window_lines(metrics) + workload_lines(metrics) \
                  + submitted_lines(metrics)


def arrival_lines(metrics: dict[str, Any]) -> list[str]:
    """Why tasks were not delivered when they had not arrived before the run ended (a summary
    from before these figures: none)."""
    arrived, tasks = metrics.get("arrived"), metrics["tasks"]
    if arrived is None or arrived >= tasks:
        return []
    return [f"{tasks - arrived} of {tasks} tasks arrive after the run's end (the last at "
            f"{metrics['last_arrival']:g} s): a --duration past it lets them be served"]


def against_reference(metrics: dict[str, Any], name: str) -> str:
    """The reference and how the run compares: its optimality against a proven optimum, else
    its gap to the best found (which a run can beat: no optimality; objectives.py)."""
    ref = metrics.get(f"reference_{name}")
    if ref is None:  # its search stopped by its cap, found none, or not run (objectives.py)
        return "no reference"
    if metrics.get("reference_method") == "exact":
        opt = metrics.get("optimality")
        return f"optimal {ref} (optimality {opt if opt is not None else '—'})"
    g = metrics.get(f"gap_{name}")
    return f"best found {ref} (gap {'—' if g is None else f'{g:+g} %'})"


def window_lines(metrics: dict[str, Any]) -> list[str]:
    """The printed summary's window counts, for an instance with windows (docs/delivery.md)."""
    if not metrics.get("windowed"):
        return []
    return [f"windows: {metrics['served_in_window']} served in window, {metrics['missed']} "
            f"missed, {metrics['late']} late (lateness {metrics['lateness']} s), "
            f"{metrics['early']} early"]


def submitted_lines(metrics: dict[str, Any]) -> list[str]:
    """What became of the tasks submitted (or cancelled) at run time (docs/tasks.md): a run
    that left some unserved says so — "delivered n/m" alone would not tell them apart."""
    n = metrics.get("submitted")
    if not n:
        return []
    counts = {k: metrics.get(f"submitted_{k}", 0)
              for k in ("served", "assigned", "waiting", "cancelled")}
    left = counts["assigned"] + counts["waiting"]
    verdict = "every one served or cancelled" if not left else f"NOT ALL SERVED: {left} left"
    return [f"submitted at run time: {n} — " + ", ".join(f"{v} {k}" for k, v in counts.items())
            + f" ({verdict})"]


def workload_lines(metrics: dict[str, Any]) -> list[str]:
    """Each robot's share and the Gini coefficients (a summary from before them: none)."""
    shares = metrics.get("workload")
    if not shares:
        return []
    each = ", ".join(f"{r} {s['served']} ({s['busy']:g} s busy, {s['distance']:g} m)"
                     for r, s in shares.items())
    return [f"workload: {each}; Gini served {metrics['gini_served']}, busy "
            f"{metrics['gini_busy']}, distance {metrics['gini_distance']}"]


DELIVERY = Delivery()
