"""The patrol mission as `mrta demo` and `mrta experiment` run it: registered under
`mrta.missions` as `patrol`. The framework's mission runner (mrta_supervisor.mission.runner) launches,
records, supervises, injects the failure and writes the summary; this hook adds what only the
patrol application can measure — collisions (the simulator's bumper counters) and the share of
the border the team came near — from the recording.

Every application package configured for patrol (patrol under ALLIANCE, patrol_murdoch under
MURDOCH, any other made with `mrta app new` that depends on patrol) holds the same launch file,
`launch/patrol_sim.launch`, and a layers file whose BorderProtection section gives the border.
"""

from __future__ import annotations

from typing import Any

from mrta_agent.runtime.params import load_layers_params
from mrta_zenoh.keys import first_chunk
from mrta_supervisor.mission import Mission, MissionRun
from mrta_supervisor.live.tasks import TaskStatus, TaskWatch

from .keys import ALL_REPORTS
from .layers import BorderParams, ReportParams
from .messages import Report
from .metrics import mission_metrics

DEFAULT_BORDER = (-20.0, -6.0, 20.0, 6.0)  # the patrol world's inner rectangle
REPORT_TASK = "report"  # the task whose layer publishes the Report


class ReportWatch(TaskWatch):
    """A report, once published, is not due again for Report/period seconds (the
    `patrol/report_due` evaluator's rule): the supervisor shows the task `done` meanwhile."""

    def __init__(self, period: float):
        self.period = period

    def feed(self):
        return [(ALL_REPORTS, Report)]

    def read(self, key: str, message) -> TaskStatus | None:
        if message.header.frame_id.strip("/") != first_chunk(key):
            return None  # a sample on robot1's key claiming to be robot2 says nothing
        return TaskStatus(REPORT_TASK, "done", self.period)


class Patrol(Mission):
    name = "patrol"
    title = "Patrol mission"
    launch = "patrol_sim.launch"
    default = True  # the dissertation's mission: what a bare `mrta demo` runs
    continuous = True  # wander and the border are never done: no architecture of routes
    better = {"collisions_total": "lower", "border_visited": "higher"}

    def metrics(self, run: MissionRun, records: list) -> dict[str, Any]:
        layers = load_layers_params(run.layers_params)
        border = layers.convert(("BorderProtection",), BorderParams) if layers is not None \
            else BorderParams()
        return mission_metrics(records, border.border() or DEFAULT_BORDER, border.distance + 1.0)

    def task_watch(self, run: MissionRun) -> TaskWatch:
        layers = load_layers_params(run.layers_params)
        report = layers.convert(("Report",), ReportParams) if layers is not None \
            else ReportParams()
        return ReportWatch(report.period)

    def describe(self, metrics: dict[str, Any]) -> list[str]:
        return [f"collisions: {metrics['collisions_total']}; border visited: "
                f"{metrics['border_visited']:.0%}"]


PATROL = Patrol()
