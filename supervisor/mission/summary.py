"""`summary.json`: what one mission run did, defined once (msgspec Structs) next to the analysis
that writes it (analysis.py) and read back from here by `mrta experiment` and the plots.

Generic over applications and architectures: who did what, coverage, the first full allocation,
the failure and its takeover beside the architecture's bound, bus traffic. What only an
application can measure (patrol: collisions, the share of the border visited) is its own
`metrics` mapping, contributed through the mission hook (mission.Mission.metrics).

An application's own *sections* (delivery: its `instance` and `allocation` log) are its own
schema, not the framework's: its Mission declares them as a `SummarySections` Struct
(`Mission.summary_sections`), the runner stores their fields at the top level of summary.json
beside the framework's, and `read_summary` validates them with that same type, found through
the summary's `mission` name (the `mrta.missions` entry point). The framework knows no section
by name; a section that would shadow a framework field is refused when the type is used.

`schema` changes when a field changes meaning. 3: sections are the application's (top-level
keys its Mission declares). A schema-2 summary still reads: its `instance` and `allocation`
were framework fields, null unless a delivery run wrote them, so null ones are dropped and the
others are read as the mission's sections — the same keys delivery declares. Schema 1 (the
patrol demo's flat dict) is refused with the schema named.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh.refusal_tally import SERVED_TWICE
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.fault_tally import CAUSES
from mrta_zenoh.files import write_text
from mrta_zenoh.installed import entry_points
from mrta_zenoh.yamlfile import did_you_mean

SCHEMA = 3
MISSIONS_GROUP = "mrta.missions"        # where a summary's `mission` names its hook
OLD_FRAMEWORK_SECTIONS = ("instance", "allocation")  # schema 2's fields, null but for delivery


class SummarySections(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """Base of an application's own summary sections: subclass it with one field per
    top-level key (`instance: DeliveryInstance`, `allocation: list[Entry]`), and name the
    subclass in the Mission's `summary_sections`."""


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
    robot: str                             # the robot struck (the role, if it struck nobody)
    killed_at: float | None = None         # when the fault began (a crash, a stall, a cut)
    fault: str = "crash"                   # crash, stall or partition (mrta_zenoh.failure)
    task: str | None = None                # what it was doing
    taken_over_by: str | None = None
    takeover_seconds: float | None = None
    bound_seconds: float | None = None     # the architecture's bound for the robot that took over
    bound_formula: str | None = None
    # the bound counts from `bound_from` (simulated s; the fault itself unless `bound_from_what`
    # names another instant: ALLIANCE's last broadcast on the task the taker heard) and rests
    # on `bound_case` (MURDOCH: the delivery delays against its bid window; no bound_seconds
    # when the run was outside it); `within_bound`: the takeover was
    bound_from: float | None = None
    bound_from_what: str | None = None
    bound_case: str | None = None
    within_bound: bool | None = None
    # the role the fault named the robot by (`@first`: mrta_zenoh/fault_roles.py), when it did
    role: str | None = None


# run_status (supervisor/mission/run_watch.py): every process ran throughout and the recording covers
# the mission; a process lost its token while the run was on (stopped or cut off: the run is not
# what its seed says); the recording does not cover the mission (the figures cover part of it)
COMPLETE, DISTURBED, INCOMPLETE = "complete", "disturbed", "incomplete"


END_SLACK = 1.0  # simulated s: a recording that ends earlier than this before the end is cut


class Disturbance(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True):
    """A process of the run whose liveliness token went while the run was on (not a crash the
    run injected): `process` a robot id, a lockstep participant's name, `recorder` or
    `simulator`; `lost_at` / `back_at` in simulated seconds (back_at None: not before the end)."""

    process: str
    lost_at: float
    back_at: float | None = None
    # how its process ended when it ended by itself before the run did ("killed by SIGKILL",
    # "exited with code 1"): a SIGKILLed dispatcher or recorder used to leave no summary at all
    ended: str | None = None


class Refusal(msgspec.Struct, forbid_unknown_fields=True):
    """What a process of the run (`receiver`: a robot, a dispatcher) refused of what it heard:
    `count` samples or claims of `kind` from `sender` for `reason` (mrta_zenoh/refusal_tally.py;
    `forged`: no process of the run would have said it, which makes the run disturbed)."""

    receiver: str
    sender: str
    kind: str
    reason: str
    count: int
    forged: bool


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
    by_kind: dict[str, int] = {}  # coordination samples of each kind (results: messages.<kind>)


class Declared(msgspec.Struct, forbid_unknown_fields=True):
    """A robot a decider left out of its plan (Decision.out): `robot`, `reason` (stalled,
    silent, crashed), from `at` until `until` (None: to the end of the run)."""

    robot: str
    reason: str
    at: float
    until: float | None = None
    by: str = ""  # the decider (central: the dispatcher)


class Decisions(msgspec.Struct, forbid_unknown_fields=True):
    """The allocation decisions an architecture's messages record (Architecture.decision): how
    many, their computation time — the machine's, like `wall_seconds`: the one part of a
    lockstep run its seed does not fix — and the objective they optimised."""

    count: int
    median_ms: float | None
    max_ms: float | None
    objective: str | None = None
    # how many were searches stopped by their time cap (Decision.capped): then the run's
    # allocation depends on the machine, and a lockstep run is not exact
    capped: int = 0
    # the robots each decider left out of its plan, and why, from when until when (issue 51.2:
    # a stall the dispatcher declared was named nowhere)
    declared: list[Declared] = []


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
    # every other subject fault of a combined spec (`crash:robot1@5,stall:robot3@9`), each
    # reported as `failure` is — it used to report the first only (issue 51.5)
    other_failures: list[FailureReport] = []
    # in lockstep a message counts as heard at its stamp (plus any injected latency), so the
    # instant a takeover bound counts from (`failure.bound_from`) is exact
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
    # when the mission's work was over (nothing left to serve: Mission.ended_at), before the
    # duration: the figures cover the run up to then; None: it ran to its duration
    ended_at: float | None = None
    decisions: Decisions | None = None   # None: the architecture records none
    # what injected faults did to coordination messages, summed over the robots by cause
    # (fault_effects.py: lost, delayed, cut_off, out_of_range); {}: nothing was touched
    fault_effects: dict[str, int] = {}
    # what the run's processes refused of what they heard, by receiver, sender, kind and reason
    # (fault_effects.refused_traffic); a forged entry makes the run disturbed
    refused: list[Refusal] = []
    # lockstep participant tokens of names that are no process of the run, seen while it was
    # on: reported, never a disturbance (a stranger cannot make a run inexact)
    strangers: list[str] = []
    # the signal that stopped the run before its end ("Ctrl-C", "SIGTERM"): its figures cover
    # it up to then (None: it ran to its end)
    interrupted: str | None = None
    schema: int = SCHEMA
    # the application's own sections (its Mission's `summary_sections` type): written at the
    # top level of summary.json, not under this name (write_summary / read_summary)
    sections: SummarySections | None = None


SECTIONS_FIELD = "sections"
# written only when there is something to say
QUIET_WHEN_EMPTY = ("refused", "strangers", "other_failures", "interrupted")
FRAMEWORK_KEYS = frozenset(f.encode_name for f in msgspec.structs.fields(Summary)
                           if f.name != SECTIONS_FIELD)


def check_sections_type(mission: str, kind: Any) -> type[SummarySections] | None:
    """A mission's declared sections type, checked: a SummarySections subclass whose keys
    shadow no framework field (None: the mission has no sections)."""
    if kind is None:
        return None
    if not (isinstance(kind, type) and issubclass(kind, SummarySections)):
        raise ConfigError(f"mission {mission!r}: summary_sections must be a subclass of "
                          f"mrta_supervisor.mission.summary.SummarySections, got {kind!r:.60}")
    clash = sorted({f.encode_name for f in msgspec.structs.fields(kind)} & FRAMEWORK_KEYS)
    if clash:
        raise ConfigError(f"mission {mission!r}: its summary sections {', '.join(clash)} "
                          "would shadow the framework's fields of the same name")
    return kind


def checked_sections(mission: str, kind: Any, value: Any) -> SummarySections | None:
    """What a mission's `sections` hook returned, as its declared type (a mapping is converted
    and validated; a section it did not declare is a ConfigError naming it)."""
    kind = check_sections_type(mission, kind)
    if value is None or value == {}:
        return None
    if kind is None:
        names = ", ".join(sorted(value)) if isinstance(value, dict) else type(value).__name__
        raise ConfigError(f"mission {mission!r} returned summary sections ({names}) but "
                          "declares no summary_sections type for them")
    if isinstance(value, kind):
        return value
    try:
        return msgspec.convert(value, kind)
    except msgspec.ValidationError as exc:
        raise ConfigError(f"mission {mission!r}: its summary sections do not match "
                          f"{kind.__name__}: {exc}") from None


def mission_hook(mission: str) -> Any:
    """The hook registered under `mrta.missions` as `mission` (a Mission, or its class), None
    when no installed package registers it."""
    eps = entry_points(group=MISSIONS_GROUP).select(name=mission)
    return next(iter(eps)).load() if eps else None


def sections_type(mission: str) -> type[SummarySections] | None:
    """The sections type the mission registered under `mrta.missions` as `mission` declares."""
    hook = mission_hook(mission)
    if hook is None:
        known = sorted(ep.name for ep in entry_points(group=MISSIONS_GROUP))
        raise ConfigError(f"mission {mission!r} is not installed here (no {MISSIONS_GROUP} "
                          f"entry point): its summary sections cannot be read; installed: "
                          f"{', '.join(known) or 'none'}" + did_you_mean(mission, known))
    try:
        kind = hook.summary_sections
    except AttributeError:
        raise ConfigError(f"{MISSIONS_GROUP} entry point {mission!r} is not a "
                          "mrta_supervisor.mission.Mission") from None
    return check_sections_type(mission, kind)


def summary_json(summary: Summary) -> bytes:
    """summary.json's bytes: the framework's fields, then the application's sections at the top
    level, indented for people."""
    data = msgspec.to_builtins(summary)
    for key in QUIET_WHEN_EMPTY:  # a run with nothing refused and no stranger says nothing
        if not data.get(key):
            data.pop(key, None)
    sections = data.pop(SECTIONS_FIELD, None) or {}
    data.update(sections)
    return msgspec.json.format(msgspec.json.encode(data), indent=2)


def write_summary(path: Path, summary: Summary) -> None:
    """Everything or nothing (files.write_text), as indented JSON people read too."""
    write_text(path, summary_json(summary).decode())


def read_summary(path: Path) -> Summary:
    """A run's summary, its application sections validated by the mission's own type;
    ConfigError naming the file and the field at fault."""
    try:
        data = msgspec.json.decode(Path(path).read_bytes(), type=dict[str, Any])
    except OSError as exc:
        raise ConfigError(f"cannot read the summary: {exc.strerror}", file=str(path)) from None
    except msgspec.DecodeError as exc:
        raise ConfigError(f"not a summary (JSON object) of schema {SCHEMA}: {exc}",
                          file=str(path)) from None
    schema = data.get("schema", 2)
    if schema not in (2, SCHEMA):
        raise ConfigError(f"a summary of schema {schema!r}; this version reads schemas 2 and "
                          f"{SCHEMA} (run the mission again to write one)", file=str(path))
    if schema == 2:
        for key in OLD_FRAMEWORK_SECTIONS:
            if data.get(key, 0) is None:
                del data[key]
    extra = {k: data.pop(k) for k in list(data) if k not in FRAMEWORK_KEYS}
    data["schema"] = SCHEMA  # read as this schema: the sections apart
    try:
        summary = msgspec.convert(data, Summary)
    except msgspec.ValidationError as exc:
        raise ConfigError(f"not a summary of schema {SCHEMA}: {exc}", file=str(path)) from None
    if extra:
        kind = sections_type(summary.mission)
        if kind is None:
            key = sorted(extra)[0]
            raise ConfigError(f"unknown field {key!r}: mission {summary.mission!r} declares no "
                              "summary sections" + did_you_mean(key, FRAMEWORK_KEYS),
                              file=str(path))
        try:
            summary.sections = msgspec.convert(extra, kind)
        except msgspec.ValidationError as exc:
            raise ConfigError(f"mission {summary.mission!r}'s sections: {exc}",
                              file=str(path)) from None
    return summary


def run_problem(summary: Summary) -> str | None:
    """Why a run's figures are not those of its seed, in one line (None: they are): what the
    printed summary, `mrta demo`'s exit and `mrta experiment`'s rows say."""
    lost = "; ".join(map(_disturbance_text, summary.disturbances))
    if summary.interrupted is not None:
        until = ("nothing was recorded" if summary.recorded_until is None
                 else f"the figures cover it up to {summary.recorded_until:g} s of "
                      f"{summary.duration:g} s")
        return f"the run was interrupted ({summary.interrupted}): {until}"
    if summary.run_status == INCOMPLETE:
        # the mission ends at its duration, or earlier when its work was over (ended_at)
        end = summary.duration if summary.ended_at is None else summary.ended_at
        # a file that reaches the end is incomplete because its recorder lost its session:
        # "it ends at 259.7 s of 258.6 s" said the opposite of the reason (issue 51, the
        # newcomer's walkthrough at load 50)
        until = ("it is empty" if summary.recorded_until is None
                 else f"it ends at {summary.recorded_until:g} s of {end:g} s"
                 if summary.recorded_until < end - END_SLACK
                 else "the recorder lost its session while the run was on: what was "
                      "published meanwhile never reached the file")
        return (f"the recording does not cover the whole mission ({until}"
                + (f"; {lost}" if lost else "") + ")" + _too_busy(summary.disturbances))
    if summary.run_status == DISTURBED:
        forged = forged_traffic(summary)
        ended = "; ".join(_disturbance_text(d) for d in summary.disturbances if d.ended)
        cut = "; ".join(_disturbance_text(d) for d in summary.disturbances if not d.ended)
        twice = "; ".join(f"{r.receiver} heard {r.count} from {r.sender}"
                          for r in summary.refused if r.reason == SERVED_TWICE)
        causes = ([f"a task was reported served by a second robot — served twice ({twice})"]
                  if twice else []) \
            + ([f"a process of the run ended before the run did ({ended})"] if ended else []) \
            + ([f"a process of the run was stopped or cut off ({cut})"] if cut else []) \
            + ([f"it refused forged coordination traffic ({forged})"] if forged else [])
        return ("; ".join(causes or ["disturbed"]) + ": the run is not what its seed gives"
                + _too_busy(summary.disturbances))
    capped = summary.decisions.capped if summary.decisions is not None else 0
    if summary.lockstep_exact is False and capped:
        return (f"{capped} allocation decision(s) stopped by their search's time cap: what was "
                "decided depends on the machine's speed, not only on the seed")
    if summary.lockstep_exact is False:
        # (a stranger's participant token is no cause: a mission's simulator takes part only
        # the run's processes, `mrta sim --lockstep-members`)
        why = ("the machine too busy for the lockstep timeouts, or claims in a participant's "
               "name that nobody met (a forger's StepDone: docs/security.md)")
        return (f"lockstep was not exact: {summary.lockstep_given_up} participant(s) given up, "
                f"{summary.lockstep_forgiven} claim(s) forgiven — {why}")
    return None


def _too_busy(disturbances: list[Disturbance]) -> str:
    """Why, when it is most likely the machine: several processes lost their tokens and got
    them back — none failed, each was starved past the Zenoh lease (the 20-robot walkthrough
    at load 50: 13 processes, each back within 0.1 s)."""
    back = {d.process for d in disturbances if d.back_at is not None and d.ended is None}
    if len(back) < 3:
        return ""
    return (f" — {len(back)} processes lost their tokens and got them back: the machine was "
            "too busy for the Zenoh lease (3 s); run fewer processes (--agents-per-process) "
            "or on a quieter machine")


def _disturbance_text(d: Disturbance) -> str:
    if d.ended:
        return f"{d.process} {d.ended} at {d.lost_at:g} s"
    return f"{d.process} lost its token at {d.lost_at:g} s" + (
        f", back at {d.back_at:g} s" if d.back_at is not None else "")


def refused_status(status: str, refused: list[Refusal]) -> str:
    """A complete run's status once what its processes refused is known: disturbed by forged
    traffic, or by a task reported served by a second robot (SERVED_TWICE: a cut let both
    serve it — the summary says so, never "complete")."""
    if status == COMPLETE and any(r.forged or r.reason == SERVED_TWICE for r in refused):
        return DISTURBED
    return status


def forged_traffic(summary: Summary, most: int = 4) -> str:
    """The forged refusals in one phrase ("" none): how many, and the largest entries."""
    forged = sorted((r for r in summary.refused if r.forged), key=lambda r: -r.count)
    if not forged:
        return ""
    parts = [f"{r.receiver} refused {r.count} {r.kind} of {r.sender}: {r.reason}"
             for r in forged[:most]]
    more = len(forged) - most
    return f"{sum(r.count for r in forged)} in all: " + ", ".join(parts) + (
        f", and {more} more" if more > 0 else "")


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
    for kind, count in summary.messages.by_kind.items():
        row[f"messages.{kind}"] = count
    row["ended_at"] = "" if summary.ended_at is None else summary.ended_at
    for cause in CAUSES:
        row[f"faults.{cause}"] = summary.fault_effects.get(cause, 0)
    d = summary.decisions
    row["decisions"] = "" if d is None else d.count
    row["decision_ms_median"] = "" if d is None or d.median_ms is None else d.median_ms
    row["decision_ms_max"] = "" if d is None or d.max_ms is None else d.max_ms
    for name, value in summary.metrics.items():
        if isinstance(value, (int, float, str, bool)):
            row[f"metrics.{name}"] = value
    return row
