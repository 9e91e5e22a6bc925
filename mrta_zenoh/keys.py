"""Key helpers and the keys every part shares (docs/architecture.md lists them all).

Call sites never format keys themselves: a typo in a hand-built key is a silent loss of traffic.
The core owns only what is common to any robot and any architecture — the simulation clock and
the standard per-robot topics (`cmd_vel`, `odom`, `sonar`, `ground_truth`, as a ROS robot driver
names them). Architectures and applications keep their own keys in their own packages.

Robot ids are bare (`robot1`); the ROS form `/robot1` found in old files is normalised here.
Infrastructure tokens (the clock source, recorders) live under `@mrta/…`: Zenoh matches a chunk
that starts with `@` only literally, so a supervisor watching `**` for robots never mistakes a
simulator or a recorder for a robot.
"""

from __future__ import annotations

import functools
import re

from .errors import ConfigError

CLOCK = "clock"
CLOCK_SOURCE_TOKEN = "@mrta/clock_source"       # held by whoever publishes `clock`
# `<CLOCK_SOURCE_TOKEN>/<run>/ENDED`: declared by a source that ends its run on purpose, before
# its tokens go — a source whose token goes without it died (SimClock.ended / lost)
CLOCK_SOURCE_ENDED = "ended"
RECORDER_TOKEN = "@mrta/recorder"               # prefix; one token per recorder process
ROS2_BRIDGE_TOKEN = "@mrta/ros2_bridge"         # prefix; /<robot>, held while it bridges
# prefix; /<name>: a process of a run that is neither robot nor observer (a task dispatcher),
# held while it is ready. Under `@`, so no robot watch (`**`) takes it for a robot
NODE_TOKEN = "@mrta/node"
ALL_CMD_VEL = "*/cmd_vel"
# A recording's topic for a liveliness token's changes: `@liveliness/<token key>`. Not a key on
# the bus — recordings, replay and plots share it, so it is written here once.
LIVELINESS_PREFIX = "@liveliness/"

# One key chunk: what robot and task ids may be. 64 characters is plenty for a name and keeps a
# flood of forged ids from costing more than a bounded amount of memory per id.
ID_PATTERN = r"[A-Za-z0-9_][A-Za-z0-9_\-.]{0,63}"
_ID = re.compile(rf"^{ID_PATTERN}$")
_BAD_CHARS = set("#?$ ")


class KeyExprError(ConfigError, ValueError):
    """A key expression, robot id or task id that Zenoh or our conventions would reject: bad
    input (exit 2), like every ConfigError."""


def is_id(text: str) -> bool:
    return bool(_ID.match(text))


def normalize_robot_id(robot_id: str) -> str:
    """`/robot1` → `robot1`; rejects ids that cannot be a single key chunk."""
    rid = robot_id.strip().strip("/")
    if not _ID.match(rid):
        raise KeyExprError(
            f"invalid robot id {robot_id!r:.80}: use up to 64 letters, digits, '_', '-' or '.', "
            "one key chunk")
    return rid


def task_chunk(task_id: str) -> str:
    """A task id checked to be one key chunk (task ids appear in keys, e.g. motivation/<task>)."""
    if not _ID.match(task_id):
        raise KeyExprError(f"invalid task id {task_id!r:.80}: use up to 64 letters, digits, '_', "
                           "'-' or '.', one key chunk")
    return task_id


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


def first_chunk(key: str) -> str:
    return key.split("/", 1)[0]


def validate_key_expr(expr: str) -> str:
    """Check a key expression against Zenoh's canonical rules; returns it unchanged.

    Catching these here gives the user one clear line instead of a Rust error from deep inside
    the session (a bad key expression exits 2 naming the value).
    """
    if not expr:
        raise KeyExprError("empty key expression")
    if expr.startswith("/") or expr.endswith("/"):
        raise KeyExprError(f"key expression {expr!r} must not start or end with '/'")
    for chunk in expr.split("/"):
        if chunk == "":
            raise KeyExprError(f"key expression {expr!r} has an empty chunk ('//')")
        if chunk in ("*", "**"):
            continue
        if "*" in chunk:
            raise KeyExprError(
                f"key expression {expr!r}: '*' must be a whole chunk ('a/*/b'), not {chunk!r}"
            )
        bad = _BAD_CHARS.intersection(chunk)
        if bad:
            raise KeyExprError(f"key expression {expr!r}: character {sorted(bad)[0]!r} is not allowed")
    return expr


def matches(expr: str, key: str) -> bool:
    """Does concrete `key` fall under key expression `expr` (`*` one chunk, `**` any number)?

    As in Zenoh, a wildcard never matches a chunk that starts with `@` (a verbatim chunk).

    Each expression is compiled once to a regular expression (a lockstep agent matches each
    of its subscriptions against the run's ≈ 1,100 keys when it learns them, and a
    chunk-by-chunk match in Python would make that most of an agent's first simulated second
    with 100 robots); tests/test_options.py checks it against the chunk-by-chunk rule."""
    return _compiled(expr)(key + "/") is not None


@functools.lru_cache(maxsize=4096)
def _compiled(expr: str):
    """`expr` as a regex over a key with a "/" appended, each chunk consuming itself and its
    "/": `*` one chunk not starting with "@", `**` any number of those, others literally."""
    parts = []
    for chunk in expr.split("/"):
        if chunk == "**":
            parts.append(r"(?:(?!@)[^/]+/)*")
        elif chunk == "*":
            parts.append(r"(?!@)[^/]+/")
        else:
            parts.append(re.escape(chunk) + "/")
    return re.compile("".join(parts), re.DOTALL).fullmatch
