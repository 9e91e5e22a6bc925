"""The mission runner's side of faults that name a robot by role (mrta_zenoh/fault_roles.py):
`@random` drawn before the run from the instance's own numbers, the agents that crashed
themselves as an `@first` crash asked, and whom `@first` struck, read back from the recording.

The instance's numbers: a run of an instance file (`--instance`) draws from the instance's
name; a run of an application's own instance from the mission's name (`patrol`, under every
architecture), so one instance gives one robot whatever the run seed or architecture.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping

from mrta_zenoh import instances
from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import FIRST, RANDOM, Failure, FaultKind, Faults
from mrta_zenoh.fault_roles import ASSIGNED, Assigned, draw_random, resolve_first
from mrta_zenoh.keys import first_chunk


def instance_name(run) -> str:
    """The name `@random` draws from: the instance file's, or the mission's."""
    if run.options.instance is None:
        return run.mission.name
    return instances.load(run.options.instance, run.mission.name).name


def with_random_drawn(run):
    """`run` with its `@random` fault naming the robot drawn: drawn on the run's typed faults
    (MissionRun.faults), so every later look at them, and every process, reads the id."""
    if run.faults.of(RANDOM) is None:
        return run
    try:
        drawn = draw_random(run.faults, run.robots, instance_name(run))
    except ValueError as exc:
        raise ConfigError(f"--fail {exc}") from None
    return dataclasses.replace(run, faults=drawn)


def crash_targets(faults: Faults, crashed_itself: Mapping[str, bool]) -> set[str]:
    """The robots whose agent was asked to crash: the ones named, and — for an `@first`
    crash — the one that crashed itself (`crashed_itself`: robot → whether its agent ended by
    a SIGKILL nobody here sent)."""
    named = {f.robot for f in faults.crashes() if f.robot != FIRST}
    first = faults.of(FIRST)
    if first is not None and first.kind == FaultKind.CRASH:
        named |= {r for r, yes in crashed_itself.items() if yes}
    return named


def announcements(records: Iterable) -> dict[str, float]:
    """Each robot's first assignment, as it announced it (robot → stamp), from a recording:
    what the agents resolved `@first` from."""
    out: dict[str, float] = {}
    for key, enc, _t, payload in records:
        if not key.endswith("/" + ASSIGNED) or key.count("/") != 2:
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        robot = first_chunk(key)
        if isinstance(msg, Assigned) and msg.header.frame_id.strip("/") == robot:
            out[robot] = min(out.get(robot, msg.header.stamp), msg.header.stamp)
    return out


def as_struck(faults: Faults, records: list) -> Faults:
    """`faults` with an `@first` item naming the robot it struck (dropped if it struck
    nobody): what an analysis of who did what needs — a stretch ends `lost` at its robot's
    crash, `stalled` at its stall, only once the item names that robot."""
    first = faults.of(FIRST)
    if first is None:
        return faults
    hit = struck(first, faults, records)
    return dataclasses.replace(faults, failures=tuple(
        f for f in (hit if f is first else f for f in faults.failures) if f is not None))


def struck(failure: Failure | None, faults: Faults, records: list) -> Failure | None:
    """`failure` as the robot it struck: itself when it names one, the robot `@first`
    resolved to (None: nobody was assigned before its time)."""
    if failure is None or failure.robot != FIRST:
        return failure
    return resolve_first(failure, announcements(records), faults)
