"""The delivery application's keys: a robot says on its own key that it began serving a task
(`robotN/delivery/started`) and that it finished it (`robotN/delivery/done`)."""

from __future__ import annotations

import enum

ALL_DONE = "*/delivery/done"
ALL_STARTED = "*/delivery/started"


class Event(str, enum.Enum):
    """What a robot says of a task it serves (`TaskEvent.event`, the last chunk of its key)."""

    STARTED = "started"
    DONE = "done"

    def __str__(self) -> str:
        return self.value


def event_key(robot_id: str, event: Event | str) -> str:
    return f"{robot_id}/delivery/{Event(event).value}"
