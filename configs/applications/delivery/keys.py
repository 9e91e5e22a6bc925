"""The delivery application's keys: a robot says on its own key that it began serving a task
(`robotN/delivery/started`) and that it finished it (`robotN/delivery/done`)."""

ALL_DONE = "*/delivery/done"
EVENTS = ("started", "done")


def event_key(robot_id: str, event: str) -> str:
    return f"{robot_id}/delivery/{event}"
