"""Faults that name a robot by role, so one spec works on any team (mrta_zenoh/failure.py: the
grammar): `@random` and `@first`.

* `@random` — a robot drawn from the **instance's** own numbers, never the run's: the same
  instance gives the same robot whatever the run seed, so the runs of one instance under
  several seeds (and architectures) are paired on the same struck robot. The mission runner
  draws it before the run (`draw_random`: a robot no other item names, uniformly, from
  `seeds.uniform` of the path ("instance", its name, "@random") below seed 0) and hands every
  process the spec with the robot's id in its place.
* `@first` — the robot first assigned any task before the fault's time T: the earliest to say
  so, ties to the lower id in natural order (robot2 before robot10), among the robots no other
  item names; if none was assigned before T, the fault strikes nobody. It depends on the run,
  so the agents resolve it themselves, in the one fault channel: when the spec has an `@first`
  item, each agent announces once, on `robotN/faults/assigned` (`Assigned`, stamped with its
  simulated time), the first time its decision logic holds a task, and listens to the others'
  announcements; at T each applies `first_assigned` to what it heard stamped before T. In
  lockstep a participant's time reaches T only once it has received everything published
  before, so every agent — and the runner, reading the same announcements from the recording —
  names the same robot: exact. Out of lockstep, an announcement still on its way at T is not
  counted.

Why an announcement rather than the architecture's own "who is doing what" feed: that feed is
monitoring traffic (ALLIANCE's Motivation, one sample per task per robot per tick: 4,000 a
second for 20 robots and 20 tasks) which no agent listens to; one message per robot per run
costs nothing, and the announcement is what the robot's own decision logic said, as the
feed is.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Collection, Mapping, Sequence

from .failure import FIRST, RANDOM, Failure, Faults
from .messages import Header, Message, message
from .seeds import uniform

ASSIGNED = "faults/assigned"            # robotN/faults/assigned: its first assignment
EVERY_ASSIGNED = f"*/{ASSIGNED}"


@message("mrta_msgs/Assigned")
class Assigned(Message):
    """A robot's first assignment in a run, said once (header.stamp: when, its clock)."""

    header: Header
    task_id: str


def assigned_key(robot: str) -> str:
    return f"{robot}/{ASSIGNED}"


def natural(robot: str) -> tuple:
    """robot2 before robot10: digits compare as numbers."""
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", robot))


def first_assigned(assigned: Mapping[str, float], before: float,
                   taken: Collection[str] = ()) -> str | None:
    """The robot whose first assignment (robot → stamp) came earliest before `before`, ties to
    the lower id in natural order; robots in `taken` (named by another item) are passed over.
    None: nobody was assigned before then."""
    candidates = [(t, natural(r), r) for r, t in assigned.items() if t < before
                  and r not in taken]
    return min(candidates)[2] if candidates else None


def draw_random(faults: Faults, robots: Sequence[str], instance: str) -> Faults:
    """`faults` with its `@random` item naming a robot drawn from instance `instance`'s own
    numbers (module docstring); the spec rewritten to match, so every later hop reads an id.
    ValueError when every robot is named by another item."""
    f = faults.of(RANDOM)
    if f is None:
        return faults
    free = [r for r in robots if faults.of(r) is None]
    if not free:
        raise ValueError(f"{f.spec}: every robot already has a fault")
    pick = free[int(uniform(0, "instance", instance, RANDOM) * len(free))]
    drawn = f._replace(robot=pick, spec=f.spec.replace(RANDOM, pick, 1))
    failures = tuple(drawn if g is f else g for g in faults.failures)
    items = [drawn.spec if item == f.spec else item for item in faults.items()]
    return dataclasses.replace(faults, failures=failures, spec=",".join(items))


def resolve_first(failure: Failure, assigned: Mapping[str, float], faults: Faults
                  ) -> Failure | None:
    """The `@first` failure as the robot it struck (None: nobody was assigned before its
    time), from the run's announcements."""
    taken = {g.robot for g in faults.failures if g.robot not in (FIRST, RANDOM)}
    who = first_assigned(assigned, failure.at, taken)
    return None if who is None else failure._replace(robot=who)
