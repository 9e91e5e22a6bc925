"""`mrta demo`: a thin click verb over mission.run_mission — any registered application under
any registered architecture (patrol under its own, ALLIANCE, by default) — that shows the
supervisor while the mission runs and prints the summary.

Output follows the Unix habits: the live view only on a terminal (otherwise a `t=` line at
the first refresh past every 10th simulated second, with the alarms up); the views show the
alarms, so the supervisor's alarm log lines are off; `mrta -q demo` prints no progress, only
the summary (the result) and errors; `-qq` errors only (summary.json is written either way).
Into a pipe nothing is wrapped (cli.common.console); Ctrl-C exits 130."""

from __future__ import annotations

import logging
from pathlib import Path

import click
from rich.console import Console, Group
from rich.text import Text

from mrta_zenoh.bus.options import BusOptions, check_endpoint
from mrta_zenoh.cli.common import console as make_console
from mrta_zenoh.cli.common import SEED_TYPE, OutputPath, finite_float, verbosity
from mrta_zenoh.errors import Interrupted, MrtaRuntimeError
from mrta_zenoh.failure import FaultKind
from mrta_zenoh.yamlfile import plural

from ..live.cli import LiveScreen, quiet_alarms, state_line
from .hook import MissionOptions
from .runner import reachable, run_mission
from .overrides import parse_override
from .summary import COMPLETE, INCOMPLETE, Summary, run_problem
from ..live.view import render


@click.command()
@click.option("--application", default=None,
              help="The application whose mission to run (mrta app list); default: the one "
                   "whose mission is marked default (Mission.default).")
@click.option("--architecture", default=None,
              help="Run it under this architecture (mrta arch list); default: the one the "
                   "application names. Needs an application package configured for it, "
                   "made with `mrta app new`.")
@click.option("--instance", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Run this instance file (mrta instance generate; a summary.json runs its "
                   "`instance` section): the run's packages are derived from it in "
                   "OUTPUT/instance.")
@click.option("--override", "overrides", multiple=True, metavar="GLOB.KEY.PATH=VALUE",
              callback=lambda _ctx, _param, texts: tuple(parse_override(t) for t in texts),
              help="With --instance: set a parameter in the packages derived from it, as an "
                   "experiment's overrides: do (e.g. robot*.timeout_duration=4.0). Repeatable.")
@click.option("--duration", type=finite_float(min=0, min_open=True), default=60.0,
              show_default=True, help="Simulated seconds of mission.")
@click.option("--speed", type=finite_float(min=0), default=2.0, show_default=True,
              help="Simulated seconds per wall second (0: as fast as possible).")
@click.option("--fail", default=None, metavar="FAULTS|none",
              help="Faults to inject, comma-separated: ROBOT@T (crash: SIGKILL its agent at "
                   "this simulated time), stall:ROBOT@T, partition:ROBOT@T+D, loss:P, "
                   "latency:MEAN±JITTER, range:R (docs/delivery.md, Fault grammar). Default: "
                   "the mission's own — the second robot crashes at half the duration, unless "
                   "the mission says otherwise (delivery: none).")
@click.option("--output", type=OutputPath(folder=True),
              default=Path("demo-output"), show_default=True,
              help="Folder for the recording, pictures and summary.json.")
@click.option("--seed", type=SEED_TYPE, default=0, show_default=True,
              help="The run's master seed, 0 to 2^63 − 1 (each robot derives its own stream).")
@click.option("--live/--no-live", default=None,
              help="Show the live supervisor view (default: when the output is a terminal).")
@click.option("--lockstep/--no-lockstep", default=True, show_default=True,
              help="The simulator waits for every agent at each step: the same seed gives the "
                   "same run whatever the machine's load.")
@click.option("--foxglove", "foxglove_port", type=click.IntRange(0, 65535), is_flag=False,
              flag_value=8765, default=None, metavar="[PORT]",
              help="Also serve the run live to Foxglove / Lichtblick (ws://127.0.0.1:8765).")
@click.option("--rendezvous", default=None, is_flag=False, flag_value="", metavar="[ENDPOINT]",
              callback=lambda _ctx, _param, value: shared_rendezvous(value),
              help="Run on this rendezvous (e.g. tcp/127.0.0.1:7447) instead of a private one, "
                   "so `mrta supervise`, `mrta view`, `mrta echo` and `mrta task` started in "
                   "other terminals reach the running mission. Bare: the one every other "
                   "command meets at ($MRTA_RENDEZVOUS, else tcp/127.0.0.1:7447).")
@click.option("--agents-per-process", type=click.IntRange(min=1), default=1, show_default=True,
              metavar="K",
              help="Run the robots' agents K per process (agent hosts: one Zenoh session and "
                   "one lockstep participant for K robots; the same summary as K = 1 but for "
                   "machine fields). 1: a process per robot, as on real robots.")
@click.option("--plots/--no-plots", default=True, show_default=True,
              help="Draw the run's pictures (world, timeline, the architecture's plots); "
                   "the recording and summary.json are written either way.")
@click.option("--secure", type=click.Path(file_okay=False, exists=True, path_type=Path),
              default=None, metavar="FLEET",
              help="Run on the secured fleet `mrta secure init FLEET …` wrote: its router, "
                   "each process with its own certificate (docs/security.md).")
@click.option("--recording", type=click.Choice(["full", "bus"]), default="full",
              show_default=True,
              help="What run.mcap holds: the bus and the channels a viewer draws (scene, "
                   "poses, the supervisor's state), or the bus alone — all the summary and "
                   "pictures read, for less CPU (mrta experiment's runs); `mrta replay` into "
                   "`mrta view` draws the rest.")
def demo(live: bool | None, **kwargs) -> None:
    """A mission end to end: simulator, agents and supervisor, then a summary."""
    options = MissionOptions(**kwargs)
    if options.secure is not None and (options.rendezvous is not None
                                       or options.agents_per_process > 1):
        raise click.UsageError("--secure runs on the fleet's router, each robot its own "
                               "process: not with --rendezvous or --agents-per-process")
    console = make_console()
    quiet = verbosity()
    show_live = console.is_terminal if live is None else live
    view = (_Silent() if quiet < 0 else _LiveView(console, options) if show_live
            else _Lines(console))
    if quiet < 0:  # the supervisor's lines are progress too (the recording keeps the alarms)
        logging.getLogger("mrta.supervisor").setLevel(logging.ERROR)
    if options.rendezvous is not None and quiet > -2:  # where other terminals reach the run
        console.print(f"the run's bus: {options.rendezvous} (MRTA_RENDEZVOUS={options.rendezvous} "
                      "mrta supervise|view|echo|task … reach it)", highlight=False, markup=False)
    if options.secure is not None and reachable(options) and quiet > -2:
        console.print(f"tasks at run time: a submitter of the fleet reaches the run with `mrta "
                      f"task submit … --as NAME --zenoh-config {options.secure}/NAME.json5`",
                      highlight=False, markup=False)
    if options.foxglove_port is not None and quiet > -2:
        console.print(f"Foxglove / Lichtblick: Open connection → "
                      f"ws://127.0.0.1:{options.foxglove_port}", highlight=False)
    try:
        with quiet_alarms():  # every view names the alarms (or, with -q, none is wanted)
            # -q: nobody sees the supervisor here, so it hears only the task news
            run, summary = run_mission(options, progress=None if quiet < 0 else view)
    finally:
        view.close()
    if quiet > -2:
        print_summary(console, summary, run.mission.title, run.arch.title,
                      run.mission.describe(summary.metrics))
    if summary.interrupted == "Ctrl-C":  # 130, as Unix tools do; SIGTERM is a clean stop
        raise Interrupted(f"the run so far is in {summary.output}/summary.json")
    # the figures cover part of the mission only, or a process of the run failed (a dispatcher
    # SIGKILLed from outside): summary.json says what can be known, exit 1 — unless a signal
    # asked for the end
    if summary.interrupted is None and (summary.run_status == INCOMPLETE
                                        or any(d.ended for d in summary.disturbances)):
        raise MrtaRuntimeError(f"{run_problem(summary)}; {summary.output}/summary.json says "
                               "what happened")


def shared_rendezvous(value: str | None) -> str | None:
    """--rendezvous: None (absent) keeps the run private; "" (bare) is the rendezvous every
    command meets at without options ($MRTA_RENDEZVOUS or the default); an endpoint is checked
    (exit 2 naming it when malformed)."""
    if value is None:
        return None
    if value.strip():
        return check_endpoint(value.strip(), "--rendezvous endpoint")
    return BusOptions().rendezvous_endpoint


class _Silent:
    """`-q`: no progress output."""

    def __call__(self, now: float, sup, failure, failed_at: float | None) -> None:
        pass

    def close(self) -> None:
        pass


class _Lines:
    """Without a terminal: one line of robot states (and the alarms up) at the first refresh
    past each 10th simulated second — refreshes come 4 times a wall second, so at `--speed 0`
    a line may come a few simulated seconds past its mark; it says when it was taken."""

    EVERY = 10.0

    def __init__(self, console: Console):
        self.console = console
        self.mark: int | None = None

    def __call__(self, now: float, sup, failure, failed_at: float | None) -> None:
        mark = int(now // self.EVERY)
        if mark == self.mark:
            return
        self.mark = mark
        self.console.print(f"t={now:5.1f}s  {state_line(sup.snapshot(now))}", highlight=False,
                           markup=False)

    def close(self) -> None:
        pass


class _LiveView:
    """The supervisor's live view under a header line (cli.LiveScreen)."""

    def __init__(self, console: Console, options: MissionOptions):
        self.console, self.options = console, options
        self.screen = LiveScreen(console)

    def __call__(self, now: float, sup, failure, failed_at: float | None) -> None:
        o = self.options
        what = _FAULT_WORDS.get(failure.kind, str(failure.kind)) if failure is not None else ""
        fail = "" if failure is None else (
            f" · {failure.robot} {what} at {failed_at:.1f} s" if failed_at is not None
            else f" · {failure.spec} at {failure.at:g} s")
        app = f" · {o.application}" if o.application else ""
        header = Text(f"mrta demo{app} · simulated {now:5.1f} / {o.duration:.0f} s"
                      f" · speed {o.speed or 'max'}{fail}", style="bold")
        self.screen.show(Group(header, render(sup.snapshot(now), self.console.width)))

    def close(self) -> None:
        self.screen.close()


_FAULT_WORDS = {FaultKind.CRASH: "killed", FaultKind.STALL: "stalled",
                FaultKind.PARTITION: "cut off"}


def _bound_note(f) -> str:
    """The takeover against the architecture's bound, as the summary states it: from which
    instant it counts (when not the fault itself) and the case the run was in."""
    if f.bound_formula is None:
        return ""  # a stall: no bound (the summary says why)
    # the bound is a crash's: a partitioned robot keeps its token, so it is noticed by its
    # silence alone, later (docs/murdoch.md, "Timing and the takeover bound")
    bound = "the crash bound" if f.fault == "partition" else "the bound"
    case = f", {f.bound_case}" if f.bound_case else ""
    if f.bound_seconds is None:
        return f" (no bound holds{case})"
    since = ""
    if f.bound_from_what and f.bound_from is not None and f.killed_at is not None:
        after = f.killed_at + f.takeover_seconds - f.bound_from
        since = f"{after:.2f} s after {f.bound_from_what}: "
    within = f.within_bound if f.within_bound is not None \
        else f.takeover_seconds <= f.bound_seconds  # a summary from before bound_from
    ok = "within" if within else "OVER"
    why = (": a partitioned robot keeps its token and is noticed by its silence alone"
           if f.fault == "partition" and not within else "")
    return f" ({since}{ok} {bound} {f.bound_formula} = {f.bound_seconds:.2f} s{case}{why})"


def failure_line(f) -> str:
    """One subject fault as the printed summary says it (summary.json's `failure` and each of
    `other_failures`)."""
    what = _FAULT_WORDS.get(f.fault, f.fault)
    if f.killed_at is None:
        return f"{f.role or f.robot}: {f.fault} never struck (the run did not reach it" + (
            ", or nobody was assigned a task before it)" if f.role else ")")
    if f.takeover_seconds is not None:
        return (f"{f.robot} {what} at {f.killed_at:.1f} s while doing {f.task}; "
                f"{f.taken_over_by} took over after {f.takeover_seconds:.2f} s" + _bound_note(f))
    if f.task is None:
        return f"{f.robot} {what} at {f.killed_at} s (it held no task)"
    return f"{f.robot} {what} at {f.killed_at} s; task {f.task} was not taken over before the end"


_EFFECT_WORDS = {"lost": "lost", "delayed": "heard late", "cut_off": "cut off by a partition",
                 "out_of_range": "out of range"}


def refused_lines(s: Summary, most: int = 6) -> list[str]:
    """What the run's processes refused (summary.json's `refused`), the largest first, and the
    strangers' tokens seen: each a line of the printed summary."""
    out = []
    if s.refused:
        total = sum(r.count for r in s.refused)
        forged = sum(r.count for r in s.refused if r.forged)
        out.append(f"refused: {total} samples or claims ({forged} forged)")
        for r in sorted(s.refused, key=lambda r: (not r.forged, -r.count))[:most]:
            out.append(f"  {r.receiver} refused {r.count} {r.kind} of {r.sender}: {r.reason}"
                       + (" (forged)" if r.forged else ""))
        if len(s.refused) > most:
            out.append(f"  … and {len(s.refused) - most} more (summary.json, `refused`)")
    if s.strangers:
        out.append(f"strangers' tokens (no process of the run; not counted against it): "
                   f"{', '.join(s.strangers)}")
    return out


def work_over(metrics: dict) -> str:
    """How the headline says the work was over at `ended_at` — honestly: a run that ended
    because nothing was left to serve, some task missed (its hard window passed: the window
    counts, mrta_zenoh.planning.schedule), was not "every task done"."""
    if not metrics.get("missed"):
        return "every task done"
    return (f"nothing left to serve — {metrics.get('completed', '?')} served, "
            f"{metrics['missed']} missed (hard windows passed) —")


def print_summary(console: Console, s: Summary, title: str, arch_title: str,
                  extra: list[str]) -> None:
    # nothing read as rich markup: names come from the bus (a Round's `out`, a stranger's
    # token, a refusal's sender), and one "[/bold]" in a forged message raised MarkupError here,
    # after the run, instead of a summary (issue 51, hostile probe)
    # what the simulator ran (the recording's end), and when the work was over — the headline
    # said the last completion was "simulated" while the run went on past it (issue 51)
    ran = s.recorded_until if s.recorded_until is not None else s.ended_at
    simulated = (f"{s.duration:.0f} s simulated" if s.ended_at is None else
                 f"{ran:.1f} s simulated ({work_over(s.metrics)} by {s.ended_at:.1f} s, "
                 f"where the figures end; --duration {s.duration:g})")
    console.print(Text(f"\n{title} ({arch_title}): {simulated} at speed "
                       f"{s.speed or 'max'} in {s.wall_seconds:.0f} s", style="bold"))
    for rid, spans in s.who_did_what.items():
        txt = ", ".join(f"{x.task} {x.start:.1f}–{x.end:.1f} s" for x in spans) or "idle"
        console.print(f"  {rid}: {txt}", highlight=False, markup=False)
    for f in ([s.failure] if s.failure else []) + s.other_failures:
        console.print(f"  {failure_line(f)}", highlight=False, markup=False)
    for task, c in s.coverage.items():
        console.print(f"  {task}: exactly one robot {c.exactly_one:.0%}, none {c.none:.0%}, "
                      f"more than one {c.more_than_one:.0%}", highlight=False, markup=False)
    for line in extra:
        console.print(f"  {line}", highlight=False, markup=False)
    d = s.decisions
    if d is not None and d.count:
        # an architecture that optimises a score of its own (CBBA: discounted rewards) made
        # its decisions for none of the objectives the run is measured on below — said so, not
        # "(no objective)" beside an optimality (issue 51, the newcomer's list)
        aim = (f"for {d.objective}" if d.objective else
               "for its own score, none of the objectives the run is measured on")
        console.print(f"  {plural(d.count, 'allocation decision')} ({aim}): "
                      f"computation median {d.median_ms:g} ms, max {d.max_ms:g} ms",
                      highlight=False, markup=False)
    for x in (d.declared if d is not None else ()):
        back = "" if x.until is None else f", back in the plan at {x.until:g} s"
        console.print(f"  {x.by or 'the decider'} declared {x.robot} {x.reason} at {x.at:g} s"
                      f"{back}" + (" (to the end)" if x.until is None else ""), highlight=False, markup=False)
    if s.fault_effects:
        said = ", ".join(f"{n} {_EFFECT_WORDS[c]}" for c, n in s.fault_effects.items() if n)
        console.print(f"  injected faults: {s.faults}; coordination messages {said}",
                      highlight=False, markup=False)
    for line in refused_lines(s):
        console.print(f"  {line}", highlight=False, markup=False)
    problem = run_problem(s)
    if s.interrupted is not None:
        console.print(f"  INTERRUPTED: {problem}", style="yellow", highlight=False,
                      markup=False)
    elif problem is not None:
        console.print(f"  NOT EXACT: {problem}" + ("; this run may not replay"
                                                    if s.run_status == COMPLETE else ""),
                      style="yellow", highlight=False, markup=False)
    console.print(f"  files in {s.output}: {files_line(s.files)}", highlight=False, markup=False)


def files_line(files: list[str], most: int = 3) -> str:
    """The files a run wrote, more than `most` of one kind — same stem before its first `_`,
    same extension — said as `N × stem_*.ext` where the first of them stood: the README's
    20-robot instance listed 261 names on one line (issue 51, the newcomer's list)."""
    def kind(name: str) -> tuple[str, str]:
        stem, _, rest = name.partition("_")
        return (stem, Path(name).suffix) if rest else (name, "")

    kinds: dict[tuple[str, str], list[str]] = {}
    for name in files:
        kinds.setdefault(kind(name), []).append(name)
    said = []
    for name in files:
        same = kinds[kind(name)]
        if len(same) <= most:
            said.append(name)
        elif name == same[0]:
            said.append(f"{len(same)} × {kind(name)[0]}_*{kind(name)[1]}")
    return ", ".join(said)
