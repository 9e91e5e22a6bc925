"""What one robot's delivery plugins know of time windows (docs/delivery.md, "Time windows"):
the tasks whose service its layer began — kept through their due — and those its layer gave up,
because it could no longer start them by their due. Shared by every task's layer and evaluator
of the robot (`AgentContext.share`), as the board is: the layer decides, the evaluator says the
task is expired for this robot from then on."""

from __future__ import annotations

from mrta_agent.runtime.plugins import Plugin

KEY = "delivery.windows"  # its key on the robot's blackboard


class WindowState:
    def __init__(self) -> None:
        self.started: set[str] = set()
        self.given_up: set[str] = set()

    @classmethod
    def of(cls, owner: Plugin) -> "WindowState":
        return owner.ctx.share(KEY, cls)
