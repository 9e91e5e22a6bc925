"""central (docs/central.md) as tools and the agent runtime see it: the object registered under
`mrta.architectures` as `central` — a dispatcher process that re-solves the problem at each
arrival, completion or robot loss and sends each robot its queue, and robots that serve their
queues.

Who is doing what is read from the robots' own `Progress` reports (what each set off to, and its
whole queue); decisions from the dispatcher's `Plan` records. Takeover bound: none — a lost
robot's tasks are re-planned within a dispatcher tick, then served in the order of whoever's
queue they join (docs/central.md, "Takeover").
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from mrta_zenoh.architectures import Decision, Takeover, TakeoverBound, declared_out
from mrta_zenoh.bus import Bus
from mrta_zenoh.clock import Clock

from ..route.architecture import RouteArchitecture
from ..runtime.architecture import Prepared
from ..runtime.host import AgentOptions
from ..runtime.loop import Agent
from . import params as central_params
from .agent import CentralCoordinator
from .messages import Plan, Progress, Queue, Queued

if TYPE_CHECKING:
    import numpy as np

DISPATCHER = "dispatcher"  # the dispatcher's process name (and lockstep participant)
SUBJECT_KINDS = ("queue", "queued")  # published under a sub-key: the robot, the task


class Central(RouteArchitecture):
    name = "central"
    title = "central"
    namespace = "central"
    executable = "central/agent"
    command = "central"
    param_stem = "central"
    bound_formula = ("none: re-planned within a dispatcher tick and a robot tick + 2 × delay, "
                     "then served in its new queue's order")
    messages = {"queue": Queue, "progress": Progress, "queued": Queued, "plan": Plan}
    coordination_kinds = ("queue", "progress")
    progress_type = Progress
    processes = (DISPATCHER,)
    objective = "minsum"
    decision_kinds = ("plan",)
    takes_submitted = True  # the dispatcher re-plans with it (dispatcher.py, tasks_added)
    logger_name = "mrta.central"

    def has_subkeys(self, kind: str) -> bool:
        """Queues go to their robot (`dispatcher/central/queue/robot1`), each queued task of a
        robot under its own key (`robot1/central/queued/t3`)."""
        return kind in SUBJECT_KINDS

    def prepare(self, options: AgentOptions) -> Prepared:
        return self.route_prepared(options.robot_id, central_params.load_params(
            options.robot_params, options.tasks_params, options.layers_params))

    def coordinator(self, prepared: Prepared) -> CentralCoordinator:
        return CentralCoordinator(prepared.robot_id, prepared.params, prepared.plugins,
                                  DISPATCHER)

    def process_agent(self, name: str, config: Path, bus: Bus, clock: Clock,
                      rng: np.random.Generator | None = None) -> Agent:
        """The dispatcher's agent from a package's config folder, the files its launch file
        gives `mrta dispatcher` (its parameters, the instance; the instance's own
        `application:` key names its kind)."""
        from .api import DispatcherOptions, dispatcher_agent, prepare  # api imports this module
        params, problem, instance = prepare(DispatcherOptions(
            config / f"dispatcher_{self.param_stem}_params.yaml", config / "instance.yaml",
            name=name))
        return dispatcher_agent(name, params, problem, bus, clock, rng, instance)

    def decision(self, sender: str, key: str, message: object) -> Decision | None:
        if not isinstance(message, Plan) or sender != DISPATCHER:
            return None
        return Decision(sender, message.header.stamp, message.solve_ms, message.objective,
                        capped=message.capped,
                        out=declared_out(message.out))

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """How soon a lost robot's task is in another robot's queue: the dispatcher's next tick
        (it learns of the loss at a tick) and the robot's (it hears the queue at its next one),
        with no delivery delay — not when it is served (module docstring)."""
        robot = central_params.load_robot(robot_params)
        return 2.0 / robot.spin_rate

    def takeover_check(self, t: Takeover) -> TakeoverBound:
        return TakeoverBound(None, t.failed_at, case=(
            "central re-plans a lost robot's tasks at once, but whoever gets one serves it in "
            "its new queue's order, which the plan chooses: no bound on when it is served"))


CENTRAL = Central()
