"""A recorded mission run, analysed: the output folder's pictures and `summary.json`
(summary.py, the one schema) — who did what, coverage, first full allocation and takeover, all
from the robots' own messages in simulated time (ground_truth.py), exact to one agent tick —
beside the bound the architecture states, traffic, what the faults did, and the application's
own metrics and sections (its `Mission` hook). It reads the recording and the resolved run
(hook.MissionRun, its typed faults) only: runner.py calls `analyse` once the run's processes
are down; nothing here starts or watches a process.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, Sequence

import msgspec

from mrta_zenoh import keys
from mrta_zenoh.architectures import Architecture, Takeover
from mrta_zenoh.clock import EPSILON
from mrta_zenoh.codec import DecodeError, decode
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import Failure, FaultKind
from mrta_zenoh.fault_roles import ASSIGNED
from mrta_zenoh.fault_tally import TALLY
from mrta_zenoh.refusal_tally import REFUSED
from mrta_zenoh.lockstep.protocol import STATUS, LockstepStatus
from mrta_zenoh.recording import Recovered, read_recording

from mrta_zenoh.tasks.messages import INTAKE

from . import roles
from .fault_effects import fault_effects, refused_traffic
from .ground_truth import decisions, intervals_from
from .hook import Mission, MissionRun
from .plots import ROBOTS_TITLE, Panel, TimeBase, draw_timeline
from .summary import (COMPLETE, Coverage, Disturbance, FailureReport, MessageRates,
                      Span, Summary, checked_sections, refused_status, write_summary)
from .run_watch import RECORDER, SIMULATOR, run_status


def mission_sections(run: MissionRun, records: list) -> Any:
    """The mission hook's own summary sections, as the type it declares (summary.py checks
    them: a section it did not declare is a ConfigError, not a silently dropped one)."""
    return checked_sections(run.mission.name, run.mission.summary_sections,
                            run.mission.sections(run, records))


def folder_state(folder: Path) -> dict[str, tuple[int, int, int]]:
    """What is in `folder` now (name → inode, size, mtime in ns): after the run, the files that
    are new or changed are exactly those this run wrote — a file an earlier run left there is
    neither (the run holds the folder's lock, so nobody else wrote into it meanwhile)."""
    out = {}
    for p in folder.iterdir():
        if p.is_file() and not p.name.startswith("."):
            st = p.stat()
            out[p.name] = (st.st_ino, st.st_size, st.st_mtime_ns)
    return out


def analyse(run: MissionRun, failure: Failure | None, failed_at: float | None,
            wall: float, before: dict[str, tuple[int, int, int]] | None = None,
            disturbances: Sequence[Disturbance] = (), strangers: Sequence[str] = (),
            interrupted: str | None = None) -> Summary:
    """The summary of a recorded run, written to summary.json; `before` is the output
    folder's state before the run (folder_state), so `files` lists what this run wrote;
    `disturbances`: what the run's processes lost while it was on, `strangers`: tokens of
    names that are none of them (run_watch.py). A run whose processes refused forged
    coordination traffic (fault_effects.refused_traffic) is disturbed too. `interrupted`: the
    signal that stopped the run early (Ctrl-C, SIGTERM), said in the summary."""
    output = run.options.output
    try:
        records = read_recording(output / "run.mcap")
    except ConfigError:
        if not any(d.process == RECORDER and d.ended for d in disturbances):
            raise
        # the recorder died before it wrote a whole chunk: nothing was recorded, and the summary
        # says so (incomplete, the recording empty) rather than nothing at all
        records = Recovered()
        records.complete = False
    tb = TimeBase(records)
    t0 = 0.0
    recorded_until = max((tb(t) for _, _, t, _ in records), default=None)
    # a run ends at its duration, or when the mission's work was over (Mission.ended_at): its
    # figures cover it up to then
    ended_at = run.mission.ended_at(run, records)
    end = run.options.duration if ended_at is None else min(ended_at, run.options.duration)
    t1 = (run.options.duration if recorded_until is None else recorded_until) \
        if ended_at is None else end
    status = run_status(list(disturbances), recorded_until, end)
    # the task intake's refusals (mrta_zenoh.tasks) are listed too; none of them is forged
    # coordination: a refused request never entered the run. The simulator's: a participant
    # token under a member's name that outlived the member's process (lockstep/ended.py)
    refused = refused_traffic(records, [*run.robots, *run.arch.processes, INTAKE, SIMULATOR])
    status = refused_status(status, refused)
    role, failure = failure, roles.struck(failure, run.faults, records)
    if role is not None and failure is None:  # an @first fault that struck nobody
        failed_at = None
    # what the robots did, from their own messages in simulated time (ground_truth.py) — not
    # the supervisor's view, which lags by its monitors' timeouts
    # a crashed robot's reports end at its crash; a stalled or partitioned one's claims are kept
    # (it may well still say it is on its task: what matters is who took it over, and when)
    # every subject fault of the spec is reported, not only the first (issue 51.5): each as it
    # struck (a role resolved) and if the run reached its time
    reach = end if recorded_until is None else min(end, recorded_until)
    others = [(f, roles.struck(f, run.faults, records)) for f in run.faults.failures
              if role is None or f is not role and f.robot != role.robot]
    others = [(f, hit, hit.at if hit is not None and hit.at <= reach + EPSILON else None)
              for f, hit in others]
    failures = [(f.robot, at) for f, at in [(failure, failed_at)] + [(h, a) for _, h, a in others]
                if f is not None and f.kind == FaultKind.CRASH and at is not None]
    intervals = intervals_from(records, run.arch, t1, run.arch.doing_stale_after, failures)
    if run.options.plots:
        # the timeline draws the same ground truth: it agrees with the summary, and one seed
        # gives one picture (a crash's time is exact in lockstep; the recorded liveliness is not)
        draw_timeline(output / "timeline.png", run.app,
                      [Panel(ROBOTS_TITLE, intervals,
                             {r: [(at, end)] for r, at in failures if r in run.robots})],
                      (t0, end), tb.label, ended_at=None if ended_at is None else end)
        run.arch.plots(output / "run.mcap", run.robots, run.app.tasks(), output, records)
    who = {rid: [Span(t, round(a, 3), round(b, 3))
                 for t, a, b in sorted(intervals.get(rid, []), key=lambda x: x[1])]
           for rid in run.robots}
    report = takeover_report(run, failure, failed_at, intervals, records, tb) \
        if failure else None
    if role is not None and role.robot != (failure.robot if failure else None):
        report = report or FailureReport(role.robot, None, fault=str(role.kind))
        report.role = role.robot
    more = []
    for f, hit, at in others:
        more.append(takeover_report(run, hit, at, intervals, records, tb) if hit is not None
                    else FailureReport(f.robot, None, fault=str(f.kind)))
        if f.robot != more[-1].robot:
            more[-1].role = f.robot
    given_up, forgiven = lockstep_trouble(records) if run.options.lockstep else (0, 0)
    faults = run.faults
    made = decisions(records, run.arch, end)
    summary = Summary(
        mission=run.mission.name, application=run.package.name, architecture=run.arch.name,
        duration=run.options.duration, speed=run.options.speed, seed=run.options.seed,
        wall_seconds=round(wall, 1), robots=run.robots, who_did_what=who,
        lockstep=run.options.lockstep, faults=faults.spec or "none",
        lockstep_exact=(given_up + forgiven == 0 and status == COMPLETE
                        and not (made is not None and made.capped))
        if run.options.lockstep else None,
        lockstep_given_up=given_up, lockstep_forgiven=forgiven, run_status=status,
        disturbances=list(disturbances),
        recorded_until=None if recorded_until is None else round(recorded_until, 3),
        first_full_allocation=full_allocation(run.mission, intervals, run.app.tasks()),
        coverage=coverage(intervals, run.app.tasks(), t0, t1),
        # up to the duration asked for: the last instant also holds what processes say as they
        # stop, recorded or not as the shutdown races the recorder
        messages=message_rates(records, run.arch, end - t0, tb),
        ended_at=None if ended_at is None else round(end, 3),
        decisions=made,
        fault_effects=fault_effects(records, [*run.robots, *run.arch.processes], end),
        refused=refused, strangers=list(strangers), interrupted=interrupted,
        metrics=run.mission.metrics(run, records), failure=report, other_failures=more,
        output=str(output), files=[], sections=mission_sections(run, records))
    # what this run wrote: new or changed files (an earlier run's are neither), and the
    # summary itself, written next
    before = before or {}
    summary.files = sorted({name for name, state in folder_state(output).items()
                            if before.get(name) != state} | {"summary.json"})
    write_summary(output / "summary.json", summary)
    return summary


def takeover_report(run: MissionRun, failure: Failure, failed_at: float | None,
                    intervals: dict, records: list, time_of: Callable[[int], float]
                    ) -> FailureReport:
    """What became of the failed robot's task: who took it over, when, and against which
    bound — the architecture's (`Architecture.takeover_check`), counted from the instant it
    names and in the case the run was in."""
    report = FailureReport(failure.robot, failed_at, fault=str(failure.kind))
    if failed_at is None:
        return report
    task = next((t for t, a, b in intervals.get(failure.robot, [])
                 if a <= failed_at <= b + 0.5), None)
    report.task = task
    taken = sorted((a, r) for r, iv in intervals.items() if r != failure.robot
                   for t, a, b in iv if t == task and a >= failed_at - 1e-6) if task else []
    if not taken:
        return report
    t_take, by = taken[0]
    report.taken_over_by = by
    report.takeover_seconds = round(t_take - failed_at, 2)
    if failure.kind == FaultKind.STALL:
        # the bound is for silence (a crash, a partition); a stalled robot keeps talking, so
        # what detects it is the architecture's own progress check (ALLIANCE's φ, MURDOCH's
        # progress_timeout) — no bound here
        return report
    options = run.options
    bound = run.arch.takeover_check(Takeover(
        task, failure.robot, failed_at, by, t_take, run.robot_params(by), records, time_of,
        roles.as_struck(run.faults, records), options.seed, options.lockstep))
    report.bound_formula = run.arch.bound_formula
    report.bound_seconds = None if bound.seconds is None else round(bound.seconds, 2)
    report.bound_from = round(bound.since, 2)
    report.bound_from_what = bound.since_what or None
    report.bound_case = bound.case or None
    report.within_bound = bound.holds(t_take)
    return report


def lockstep_trouble(records) -> tuple[int, int]:
    """(participants given up, claims forgiven) over the run: the simulator's last lockstep
    status says (its counts only grow within a run). Either makes the run inexact."""
    given_up = forgiven = 0
    for key, _, _, payload in records:
        if key != STATUS:
            continue
        try:
            status = decode(LockstepStatus.TYPE_NAME, payload)
        except DecodeError:
            continue  # not the simulator's (on an open bus anyone may publish there)
        given_up, forgiven = max(given_up, status.given_up), max(forgiven, status.forgiven)
    return given_up, forgiven


def coverage(intervals: dict, tasks: list[str], t0: float, t1: float,
             step: float = 0.1) -> dict[str, Coverage]:
    """Per task: share of [t0, t1] with exactly one robot on it, none, more than one."""
    out = {}
    n = max(1, int((t1 - t0) / step))
    for task in tasks:
        spans = [(a, b) for iv in intervals.values() for tk, a, b in iv if tk == task]
        one = none = many = 0
        for k in range(n):
            t = t0 + (k + 0.5) * step
            c = sum(1 for a, b in spans if a <= t < b)
            one += c == 1
            none += c == 0
            many += c > 1
        out[task] = Coverage(round(one / n, 3), round(none / n, 3), round(many / n, 3))
    return out


UNCOUNTED = (keys.CLOCK, STATUS)  # infrastructure, best effort: not what a run's robots did


def is_traffic(key: str) -> bool:
    """Whether a recorded sample counts as bus traffic: not liveliness (`@…`), nor the
    simulator's clock and lockstep status. The clock goes out best effort every physics step,
    and the transport drops a few of them when the recorder falls behind — counting them made
    two runs of one seed differ in their rates (and results.csv in its bytes). Nor the fault
    channel's own words (`robotN/faults/…`: an `@first` announcement, a tally): the
    experiment's instrument, not the architecture's traffic — a fault would raise the counts
    it is compared on; nor a process's tally of what it refused (`<name>/refused/tally`)."""
    return not key.startswith("@") and key not in UNCOUNTED \
        and not key.endswith((f"/{ASSIGNED}", f"/{TALLY}", f"/{REFUSED}"))


class _Stamp(msgspec.Struct):
    stamp: float


class _Stamped(msgspec.Struct):
    """Any message's header stamp; the rest of its map is skipped (unknown fields ignored)."""

    header: _Stamp | None = None


_read_stamp = msgspec.msgpack.Decoder(_Stamped).decode  # built at import, on one thread


NOT_A_MAP = -math.inf  # sent_at of a payload that is no message map: counted by its log time


def sent_at(payload: bytes) -> float | None:
    """The simulated time a sample was sent at, as its sender stamped it; None for a message
    without a header, NOT_A_MAP for a payload that is not a message."""
    try:
        header = _read_stamp(payload).header
    except (msgspec.DecodeError, msgspec.ValidationError):
        return NOT_A_MAP
    if header is None:
        return None
    return header.stamp if math.isfinite(header.stamp) else NOT_A_MAP


def message_rates(records, arch: Architecture, seconds: float,
                  time_of=None) -> MessageRates:
    """Samples per simulated second on the bus (`is_traffic`); what robots tell
    each other (the architecture's coordination kinds, sub-keys included: MURDOCH's
    `robot1/murdoch/announcement/t1`); and all its namespace's samples (with monitoring).

    With `time_of` (log time → run seconds), only samples *sent* in [0, seconds) count, so
    that one seed gives one count whatever the machine's load:
    * a sample with a header counts by its own stamp — not by its log time, which is the clock
      the recorder had last heard when it arrived, so that samples at the window's edges moved
      in or out with the recorder's lag (8 of 20 runs under load differed by −16 to +8);
    * one without (a robot's Twist on cmd_vel) counts by the next stamped sample its robot's
      agent sent (its architecture's keys, e.g. the Motivation of the same or the next tick):
      one sender's samples keep their order on the way and in the file (ties in log time
      are kept in write order). A command its agent said nothing after — the zero velocity
      it sends as it stops, recorded or not as the shutdown races the recorder — is not
      counted;
    * a headerless sample of no robot, or a payload that is no message, by its log time."""
    total = coordination = namespace = 0
    by_kind = dict.fromkeys(arch.coordination, 0)
    waiting: dict[str, list[str]] = {}  # robot → its headerless samples since its last stamp

    def count(key: str) -> None:
        nonlocal total, coordination, namespace
        total += 1
        if arch.is_namespace_key(key):
            namespace += 1
            if arch.is_coordination_key(key):
                coordination += 1
                by_kind[key.split("/")[2]] += 1

    for key, _, t, payload in records:
        if not is_traffic(key):
            continue
        if time_of is None:
            count(key)
            continue
        stamp = sent_at(payload)
        robot = key.split("/", 1)[0]
        if stamp is None and "/" in key:
            waiting.setdefault(robot, []).append(key)
            continue
        if stamp is None or stamp == NOT_A_MAP:
            if time_of(t) < seconds - EPSILON:
                count(key)
            continue
        if arch.is_namespace_key(key):
            before = waiting.pop(robot, ())
            if stamp < seconds - EPSILON:
                for k in before:
                    count(k)
        if stamp < seconds - EPSILON:
            count(key)
    return MessageRates(round(total / seconds, 1), round(coordination / seconds, 1),
                        arch.namespace, round(namespace / seconds, 1), list(arch.coordination),
                        total, by_kind)



def full_allocation(mission: Mission, intervals: dict, tasks) -> float | None:
    """The summary's `first_full_allocation`: for a mission whose tasks all need a robot at
    once (Mission.instantaneous), None for others."""
    return first_full_allocation(intervals, tasks) if mission.instantaneous else None


def first_full_allocation(intervals: dict, tasks) -> float | None:
    """The first time every task was held by some robot (None: never during the run)."""
    events = sorted({a for iv in intervals.values() for _, a, _ in iv})
    for t in events:
        held = {task for iv in intervals.values() for task, a, b in iv if a <= t <= b}
        if set(tasks) <= held:
            return round(t, 2)
    return None
