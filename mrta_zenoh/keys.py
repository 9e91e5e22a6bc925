"""Every key the project publishes on, in one place (DESIGN §3), plus key-expression rules.

Call sites never format keys themselves: a typo in a hand-built key is a silent loss of traffic.
Robot ids are bare (`robot1`); the ROS form `/robot1` found in old files is normalised here.
"""

from __future__ import annotations

import re

CLOCK = "clock"
SIMULATOR_TOKEN = "simulator"
ALL_INTER_ROBOT_COMMUNICATION = "*/alliance/inter_robot_communication"
ALL_MOTIVATION = "*/alliance/motivation/*"
ALL_CMD_VEL = "*/cmd_vel"

_ID = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_\-.]*$")
_BAD_CHARS = set("#?$ ")


class KeyError_(ValueError):
    """A key expression or robot id that Zenoh would reject (named to avoid shadowing KeyError)."""


def normalize_robot_id(robot_id: str) -> str:
    """`/robot1` → `robot1`; rejects ids that cannot be a single key chunk."""
    rid = robot_id.strip().strip("/")
    if not _ID.match(rid):
        raise KeyError_(
            f"invalid robot id {robot_id!r}: use letters, digits, '_', '-' or '.', one key chunk"
        )
    return rid


def _task(task_id: str) -> str:
    if not _ID.match(task_id):
        raise KeyError_(f"invalid task id {task_id!r}: it must be a single key chunk")
    return task_id


def inter_robot_communication(robot_id: str) -> str:
    return f"{robot_id}/alliance/inter_robot_communication"


def motivation(robot_id: str, task_id: str) -> str:
    return f"{robot_id}/alliance/motivation/{_task(task_id)}"


def sensory_feedback(robot_id: str) -> str:
    return f"{robot_id}/alliance/sensory_feedback"


def agent_token(robot_id: str) -> str:
    return f"{robot_id}/alliance/agent"


def robot_topic(robot_id: str, topic: str) -> str:
    """A per-robot topic named relative to the robot, as sensor `topic_name`s are (`sonar`)."""
    topic = topic.strip("/")
    validate_key_expr(topic)
    return f"{robot_id}/{topic}"


def cmd_vel(robot_id: str) -> str:
    return f"{robot_id}/cmd_vel"


def sonar(robot_id: str) -> str:
    return f"{robot_id}/sonar"


def odom(robot_id: str) -> str:
    return f"{robot_id}/odom"


def ground_truth(robot_id: str) -> str:
    return f"{robot_id}/ground_truth"


def bumper(robot_id: str) -> str:
    return f"{robot_id}/bumper"


def patrol_report(robot_id: str) -> str:
    return f"{robot_id}/patrol/report"


def robot_tokens(robot_id: str) -> str:
    """Liveliness expression meaning 'any process of this robot is alive' (DESIGN §7)."""
    return f"{robot_id}/**"


def first_chunk(key: str) -> str:
    return key.split("/", 1)[0]


def validate_key_expr(expr: str) -> str:
    """Check a key expression against Zenoh's canonical rules; returns it unchanged.

    Catching these here gives the user one clear line instead of a Rust error from deep inside
    the session (issue: a bad key expression exits 2 naming the value).
    """
    if not expr:
        raise KeyError_("empty key expression")
    if expr.startswith("/") or expr.endswith("/"):
        raise KeyError_(f"key expression {expr!r} must not start or end with '/'")
    for chunk in expr.split("/"):
        if chunk == "":
            raise KeyError_(f"key expression {expr!r} has an empty chunk ('//')")
        if chunk in ("*", "**"):
            continue
        if "*" in chunk:
            raise KeyError_(
                f"key expression {expr!r}: '*' must be a whole chunk ('a/*/b'), not {chunk!r}"
            )
        bad = _BAD_CHARS.intersection(chunk)
        if bad:
            raise KeyError_(f"key expression {expr!r}: character {sorted(bad)[0]!r} is not allowed")
    return expr


def matches(expr: str, key: str) -> bool:
    """Does concrete `key` fall under key expression `expr` (`*` one chunk, `**` any number)?"""
    return _match(expr.split("/"), key.split("/"))


def _match(pat: list[str], parts: list[str]) -> bool:
    if not pat:
        return not parts
    head = pat[0]
    if head == "**":
        return any(_match(pat[1:], parts[i:]) for i in range(len(parts) + 1))
    if not parts:
        return False
    if head == "*" or head == parts[0]:
        return _match(pat[1:], parts[1:])
    return False


def with_namespace(namespace: str, key: str) -> str:
    return f"{namespace}/{key}" if namespace else key


def strip_namespace(namespace: str, key: str) -> str:
    if namespace and key.startswith(namespace + "/"):
        return key[len(namespace) + 1:]
    return key
