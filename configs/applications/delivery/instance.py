"""The delivery instance as the agents' layers file carries it (section `Delivery`) and as
`instance.yaml` states it for the generator: robots (start, speed, capabilities) and tasks
(position, arrival, service, capability). Typed (msgspec), so a bad value is an error naming
file, line and key when the agent loads its parameters, before anything runs.

Both packages (ALLIANCE's `delivery`, MURDOCH's `delivery_murdoch`) carry the same section, so
every robot, whatever its architecture, and the mission hook read one instance.
"""

from __future__ import annotations

import math
from typing import Annotated

import msgspec

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Finite

Point = Annotated[tuple[Finite, Finite], msgspec.Meta(title="x, y in metres")]
NonNegative = Annotated[float, msgspec.Meta(ge=0.0, le=1e9)]
Positive = Annotated[float, msgspec.Meta(gt=0.0, le=100.0)]


class RobotSpec(msgspec.Struct, forbid_unknown_fields=True):
    start: Point
    speed: Positive                      # m/s the robot drives at (its commanded cap)
    capabilities: tuple[str, ...] = ()
    heading: Finite = 0.0                # degrees, the start heading


class TaskSpec(msgspec.Struct, forbid_unknown_fields=True):
    position: Point
    arrival: NonNegative = 0.0           # s: when the task appears
    service: NonNegative = 0.0           # s: how long a robot must stay at it
    capability: str = ""                 # what it needs ("": any robot)


class DeliveryParams(msgspec.Struct, forbid_unknown_fields=True):
    """The layers file's `Delivery` section (and instance.yaml's body)."""

    robots: dict[str, RobotSpec] = {}
    tasks: dict[str, TaskSpec] = {}
    tolerance: Annotated[float, msgspec.Meta(gt=0.0, le=5.0)] = 0.3  # m: "at the task"
    turn_rate: Annotated[float, msgspec.Meta(gt=0.0, le=3.0)] = 1.2   # rad/s at most

    def robot(self, robot_id: str) -> RobotSpec:
        spec = self.robots.get(robot_id)
        if spec is None:
            raise ConfigError(f"Delivery/robots has no entry for {robot_id!r} (it has: "
                              f"{', '.join(self.robots) or 'none'})")
        return spec

    def task(self, task_id: str) -> TaskSpec:
        spec = self.tasks.get(task_id)
        if spec is None:
            raise ConfigError(f"Delivery/tasks has no task {task_id!r} (it has: "
                              f"{', '.join(self.tasks) or 'none'})")
        return spec

    def instance(self):
        """The generic ST-SR-IA instance (mrta_supervisor.allocation), in file order. Imported
        here, not at the top: agents read this module and must not load numpy or scipy."""
        from mrta_supervisor.allocation import Instance, Robot, Task
        return Instance(
            tuple(Robot(rid, tuple(r.start), r.speed, frozenset(r.capabilities))
                  for rid, r in self.robots.items()),
            tuple(Task(tid, tuple(t.position), t.arrival, t.service, t.capability)
                  for tid, t in self.tasks.items()))

    def capable(self, robot_id: str, task_id: str) -> bool:
        need = self.task(task_id).capability
        return not need or need in self.robot(robot_id).capabilities

    def check(self) -> None:
        """What the types cannot say: every task some robot can serve."""
        for tid in self.tasks:
            if not any(self.capable(rid, tid) for rid in self.robots):
                raise ConfigError(f"Delivery/tasks/{tid}: no robot has capability "
                                  f"{self.tasks[tid].capability!r}")


def heading_to(x: float, y: float, gx: float, gy: float) -> float:
    return math.atan2(gy - y, gx - x)
