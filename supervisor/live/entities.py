"""What the supervisor holds per robot and per task."""

from __future__ import annotations

from dataclasses import dataclass, field

from mrta_zenoh.architectures import Architecture, Doing

from .holders import SampleHolder


@dataclass
class RobotInfo:
    id: str
    known: bool                 # part of the application
    busy: SampleHolder
    idle: SampleHolder
    tokens: set[str] = field(default_factory=set)
    ever_token: bool = False
    bridges: set[str] = field(default_factory=set)  # `@mrta/ros2_bridge/<id>` tokens alive
    ros2_driver: bool = False   # a ROS 2 node lives in the robot's namespace
    ever_ros2: bool = False     # … and one did since a bridge took the robot
    state: str = "offline"
    since: float = 0.0


@dataclass
class TaskInfo:
    id: str
    known: bool
    incoming: SampleHolder
    state: str = "unallocated"
    robots: tuple[str, ...] = ()
    since: float = 0.0
    # what the application said of the task (supervisor/live/tasks.py): "done", "waiting" or
    # "missed", up to `until` (None: for good); a task that is none of them needs a robot
    status: str | None = None
    until: float | None = None
    # when it was last seen waiting for a robot to be free (tasks.waits_for_a_robot): the
    # unattended clock counts from then at the earliest
    waited: float = float("-inf")


class Allocations:
    """Who holds which task: one SampleHolder per (task, robot) pair heard, high for the
    `allocated_tasks` monitor's timeout after its latest sample, and the pairs now high, by
    robot and by task."""

    def __init__(self, timeout: float):
        self.timeout = timeout
        self.holders: dict[tuple[str, str], SampleHolder] = {}
        self._by_robot: dict[str, set[str]] = {}  # robot → tasks whose holder is high
        self._by_task: dict[str, set[str]] = {}   # task → robots whose holder is high

    def sample(self, tid: str, rid: str, now: float) -> tuple[SampleHolder, bool]:
        """The pair's holder after a sample, and whether it rose (a new allocation)."""
        holder = self.holders.get((tid, rid))
        if holder is None:
            holder = self.holders[(tid, rid)] = SampleHolder(self.timeout)
        rose = holder.sample(now, tid)
        if rose:
            self._by_robot.setdefault(rid, set()).add(tid)
            self._by_task.setdefault(tid, set()).add(rid)
        return holder, rose

    def drop_robot(self, rid: str) -> list[str]:
        """Every task `rid` holds, dropped at once (its token is gone); the tasks."""
        tasks = sorted(self._by_robot.get(rid, ()))
        for tid in tasks:
            self.holders[(tid, rid)].drop()
            self._release(tid, rid)
        return tasks

    def update(self, now: float) -> list[tuple[str, str]]:
        """The (task, robot) pairs whose holder fell by `now`."""
        fell = [pair for pair, h in self.holders.items() if h.update(now)]
        for tid, rid in fell:
            self._release(tid, rid)
        return fell

    def tasks_of(self, rid: str) -> list[str]:
        return sorted(self._by_robot.get(rid, ()))

    def robots_on(self, tid: str) -> tuple[str, ...]:
        return tuple(sorted(self._by_task.get(tid, ())))

    def _release(self, tid: str, rid: str) -> None:
        self._by_robot.get(rid, set()).discard(tid)
        self._by_task.get(tid, set()).discard(rid)


class Serving:
    """Which task each robot serves now, as its architecture's own reports say (the registered
    contract's `doing`: central's and the own-route architectures' Progress name the task a
    robot is on and the queue behind it). The `allocated_tasks` monitor only says which tasks
    a robot holds — for a robot with a queue, a set — so it cannot tell which one it is on.
    A report holds for the architecture's `doing_stale_after`."""

    def __init__(self, arch: Architecture):
        self.arch = arch
        self._latest: dict[str, tuple[Doing, float]] = {}  # robot → its last report, heard at

    def feed(self) -> list[tuple[str, type]]:
        return self.arch.doing_feed()

    def read(self, key: str, message: object, now: float) -> Doing | None:
        """A sample of the feed; its Doing (None: it says nothing of tasks, or is forged)."""
        doing = self.arch.read_doing(key, message)
        if doing is not None:
            self._latest[doing.robot] = (doing, now)
        return doing

    def of(self, rid: str, now: float) -> Doing | None:
        """The robot's latest report if it still holds at `now`."""
        latest = self._latest.get(rid)
        if latest is None or now - latest[1] > self.arch.doing_stale_after:
            return None
        return latest[0]

    def clear(self) -> None:
        self._latest.clear()
