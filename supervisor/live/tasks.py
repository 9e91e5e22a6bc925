"""What an application tells the supervisor about its tasks' life cycle: a task that is done,
not due yet, or that can no longer be served (a hard time window passed with no service
started), needs no robot — it is shown `done` / `waiting` / `missed`, and no
`task_unattended` alarm is raised for it. A run ends when nothing is left to serve: every task
`done` or `missed` for good (Supervisor.all_done).

The supervisor is generic: it knows no application. An application that has such tasks (a
delivery is done once delivered; a task of an online instance is waiting until it arrives; a
periodic report is not due again until its period has passed) gives a `TaskWatch` from its
mission hook (`Mission.task_watch`, supervisor/mission/hook.py): the keys to read and what each
sample says, plus what is known in advance. A status holds for `seconds` from when it is
heard (None: for good), on the supervisor's clock, so a supervisor on wall time watching a
simulated run is not misled by the senders' simulated stamps. A task on which a robot works
is `allocated` whatever its status says: the picture shows who works, the status only why
nobody needs to.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal, Mapping


@dataclass(frozen=True)
class TaskStatus:
    task: str
    state: Literal["done", "waiting", "missed"]
    seconds: float | None = None  # how long it holds from when it is heard; None: for good


class TaskWatch:
    """An application's view of its tasks' life cycle (py_trees style: override what you
    need; the defaults say nothing)."""

    # tasks served one after another by fewer robots (time-extended allocation): a task
    # nobody holds may be waiting for a robot to be free (`waits_for_a_robot`). False for
    # continuous tasks (patrol's): a robot never becomes free of one, so a task left alone
    # while the others are busy is unattended
    served_in_turn: bool = False

    def feed(self) -> list[tuple[str, type]]:
        """(key expression, message type) pairs whose samples `read` understands."""
        return []

    def schedule(self) -> list[TaskStatus]:
        """What is known at the start of a run (tasks that arrive later are `waiting` for
        `seconds`: their arrival time)."""
        return []

    def read(self, key: str, message: Any) -> TaskStatus | None:
        """What a sample of the feed says of a task (None: nothing)."""
        return None

    def lapsed(self, elapsed: float) -> list[TaskStatus]:
        """What time alone has settled by `elapsed` seconds after the schedule was read (the
        supervisor's clock): a task that can no longer be served (`missed`, for good). The
        supervisor applies it only to a task that is not done and that no robot holds."""
        return []

    def servers(self, task: str) -> frozenset[str] | None:
        """The robots able to serve `task` (None: every robot), for `waits_for_a_robot`."""
        return None


def waits_for_a_robot(servers: frozenset[str] | None, states: Mapping[str, str]) -> bool:
    """Whether a task nobody holds is waiting for a robot to be free rather than unattended:
    some robot able to serve it (`servers`, None: any) is online and none of them is idle.
    With more tasks than robots (time-extended allocation) that is the normal course under an
    architecture that keeps no queue — MURDOCH auctions the task again until a robot that
    finished bids, ALLIANCE's robots take it up when they are free — whereas a queueing one
    (central, SSI, CBBA) shows the same task held, in some robot's queue. A task no online robot
    can serve, or that an idle one leaves alone, is unattended. `states`: robot → the
    supervisor's state (busy, idle, offline, unknown)."""
    able = [s for r, s in states.items() if servers is None or r in servers]
    return "busy" in able and "idle" not in able
