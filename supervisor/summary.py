"""`summary.json`: what one mission run did, defined once (msgspec Structs) next to the runner
that writes it (mission.py) and read back from here by `mrta experiment` and the plots.

Generic over applications and architectures: who did what, coverage, the first full allocation,
the failure and its takeover beside the architecture's bound, bus traffic. What only an
application can measure (patrol: collisions, the share of the border visited) is its own
`metrics` mapping, contributed through the mission hook (mission.Mission.metrics). `schema`
changes when a field changes meaning.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_text

SCHEMA = 2  # 1: the patrol demo's flat dict (application metrics at the top level)
SECTIONS = ("instance", "allocation")  # what a Mission hook may add at the top level


class Span(msgspec.Struct, forbid_unknown_fields=True):
    """One robot on one task from `start` to `end` (simulated seconds)."""

    task: str
    start: float = msgspec.field(name="from")
    end: float = msgspec.field(name="to")


class Coverage(msgspec.Struct, forbid_unknown_fields=True):
    """Shares of the run with exactly one robot on a task, none, more than one."""

    exactly_one: float
    none: float
    more_than_one: float


class FailureReport(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True):
    robot: str
    killed_at: float | None = None         # when the fault began (a crash, a stall, a cut)
    fault: str = "crash"                   # crash, stall or partition (mrta_zenoh.failure)
    task: str | None = None                # what it was doing
    taken_over_by: str | None = None
    takeover_seconds: float | None = None
    bound_seconds: float | None = None     # the architecture's bound for the robot that took over
    bound_formula: str | None = None


# run_status (supervisor/run_watch.py): every process ran throughout and the recording covers
# the mission; a process lost its token while the run was on (stopped or cut off: the run is not
# what its seed says); the recording does not cover the mission (the figures cover part of it)
COMPLETE, DISTURBED, INCOMPLETE = "complete", "disturbed", "incomplete"


class Disturbance(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True):
    """A process of the run whose liveliness token went while the run was on (not a crash the
    run injected): `process` a robot id, a lockstep participant's name, `recorder` or
    `simulator`; `lost_at` / `back_at` in simulated seconds (back_at None: not before the end)."""

    process: str
    lost_at: float
    back_at: float | None = None


class MessageRates(msgspec.Struct, forbid_unknown_fields=True):
    """Samples per simulated second on the bus: all of them, what robots tell each other
    (the architecture's `coordination` kinds, sub-keys included), and everything under its
    namespace (coordination and monitoring: ALLIANCE's Motivation panels)."""

    total_per_second: float
    coordination_per_second: float
    coordination_namespace: str
    namespace_per_second: float | None = None   # None: a summary written before it was counted
    coordination_kinds: list[str] = []
    total: int | None = None  # the samples counted (results.csv's `messages`); None: older summary


class Summary(msgspec.Struct, forbid_unknown_fields=True):
    mission: str                 # the mission (mrta.missions), e.g. patrol
    application: str             # the rqt_mrta application package that ran, e.g. patrol_murdoch
    architecture: str            # the architecture (mrta.architectures), e.g. murdoch
    duration: float              # simulated seconds asked for
    speed: float                 # simulated seconds per wall second (0: as fast as possible)
    seed: int
    wall_seconds: float
    robots: list[str]
    who_did_what: dict[str, list[Span]]
    first_full_allocation: float | None
    coverage: dict[str, Coverage]
    messages: MessageRates
    output: str
    files: list[str]
    metrics: dict[str, Any] = {}   # the application's own (its mission hook)
    failure: FailureReport | None = None
    # in lockstep a broadcast is heard the step it is sent: the takeover bound, which counts
    # from the last broadcast received, then counts from the death itself
    lockstep: bool = True
    # every fault injected, as the spec reads (`failure` is about the first robot's only):
    # `loss:0.2`, `latency:0.3±0.2`, `partition:robot1@5+10,loss:0.2` — or "none"
    faults: str = "none"
    # in lockstep, whether the run was exact: false when the simulator gave a participant up or
    # forgave a claim (a machine too busy for its timeouts) — the run then depended on the
    # machine, and `mrta experiment` runs it again (here, not on a Dask cluster: there it is
    # marked `inexact`; docs/architecture.md); None out of lockstep
    lockstep_exact: bool | None = None
    lockstep_given_up: int = 0   # participants given up, over the run
    lockstep_forgiven: int = 0   # claims forgiven, over the run
    # complete, disturbed or incomplete (COMPLETE…): a disturbed or incomplete run is not exact
    run_status: str = COMPLETE
    disturbances: list[Disturbance] = []
    recorded_until: float | None = None  # the recording's last simulated second
    # a point-task mission's instance and allocation log (Mission.sections; docs/delivery.md)
    instance: dict[str, Any] | None = None
    allocation: list[dict[str, Any]] | None = None
    schema: int = SCHEMA


def write_summary(path: Path, summary: Summary) -> None:
    """Everything or nothing (files.write_text), as indented JSON people read too."""
    write_text(path, msgspec.json.format(msgspec.json.encode(summary), indent=2).decode())


def read_summary(path: Path) -> Summary:
    """A run's summary; ConfigError naming the file and the field at fault."""
    try:
        return msgspec.json.decode(Path(path).read_bytes(), type=Summary)
    except OSError as exc:
        raise ConfigError(f"cannot read the summary: {exc.strerror}", file=str(path)) from None
    except msgspec.DecodeError as exc:
        raise ConfigError(f"not a summary of schema {SCHEMA}: {exc}", file=str(path)) from None


def run_problem(summary: Summary) -> str | None:
    """Why a run's figures are not those of its seed, in one line (None: they are): what the
    printed summary, `mrta demo`'s exit and `mrta experiment`'s rows say."""
    lost = "; ".join(f"{d.process} lost its token at {d.lost_at:g} s"
                     + (f", back at {d.back_at:g} s" if d.back_at is not None else "")
                     for d in summary.disturbances)
    if summary.run_status == INCOMPLETE:
        until = ("it is empty" if summary.recorded_until is None
                 else f"it ends at {summary.recorded_until:g} s of {summary.duration:g} s")
        return (f"the recording does not cover the whole mission ({until}"
                + (f"; {lost}" if lost else "") + ")")
    if summary.run_status == DISTURBED:
        return (f"a process of the run was stopped or cut off ({lost}): the run is not what "
                "its seed gives")
    if summary.lockstep_exact is False:
        return (f"lockstep was not exact: {summary.lockstep_given_up} participant(s) given up, "
                f"{summary.lockstep_forgiven} claim(s) forgiven — the machine was too busy for "
                "the lockstep timeouts")
    return None


def flat_metrics(summary: Summary) -> dict[str, Any]:
    """The summary as one row of scalars (what `mrta experiment` writes per run): failure and
    takeover, coverage per task, first full allocation, traffic and every scalar the
    application's hook measured (as `metrics.<name>`)."""
    row: dict[str, Any] = {}
    f = summary.failure
    row["takeover_seconds"] = "" if f is None or f.takeover_seconds is None else f.takeover_seconds
    row["taken_over_by"] = "" if f is None or f.taken_over_by is None else f.taken_over_by
    for task, c in summary.coverage.items():
        row[f"{task}.exactly_one"] = c.exactly_one
        row[f"{task}.none"] = c.none
        row[f"{task}.more_than_one"] = c.more_than_one
    row["first_full_allocation"] = ("" if summary.first_full_allocation is None
                                    else summary.first_full_allocation)
    row["messages_per_second"] = summary.messages.total_per_second
    row["coordination_messages_per_second"] = summary.messages.coordination_per_second
    row["namespace_messages_per_second"] = ("" if summary.messages.namespace_per_second is None
                                            else summary.messages.namespace_per_second)
    for name, value in summary.metrics.items():
        if isinstance(value, (int, float, str, bool)):
            row[f"metrics.{name}"] = value
    return row
