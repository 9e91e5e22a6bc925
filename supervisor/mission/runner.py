"""Running a mission, end to end, for any registered application and architecture: what `mrta
demo` and every run of `mrta experiment` do (`run_mission`).

It runs the application package's mission launch file (the simulator and one agent per robot)
through the runner `mrta launch` uses, plus a recorder, all as separate processes on a private
loopback rendezvous (from ROUTER_FROM robots on, through a router of the run's own) — or on the
rendezvous the run is given (`--rendezvous`), where other terminals reach it; this process is
the supervisor. Readiness is read from liveliness tokens (each robot's token, the
recorder's, the clock source's), never from log lines; the simulator itself starts the clock
only once every robot is up. Every process of the run gets the run's seed ($MRTA_SEED,
mrta_zenoh.seeds) and its faults ($MRTA_FAULTS: crash, stall, partition, loss, latency —
mrta_zenoh.failure, the one fault channel) from this runner's environment, and injects its own
at their simulated times (exact in lockstep). Afterwards analysis.py turns the recording into
the output folder's pictures and `summary.json`.

Framework code: it knows no application and no architecture. An application registers a
`Mission` under `mrta.missions` (hook.py); an architecture is reached through
`mrta.architectures`.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import shlex
import signal
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

from mrta_zenoh import instances, lifecycle
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.options import LEASE, LEASE_ENV, lease_from_env, private_rendezvous
from mrta_zenoh.clock import SimClock
from mrta_zenoh.errors import ConfigError, Interrupted
from mrta_zenoh.failure import FAULTS_ENV, RETIRED_CRASH_ENV, Failure, fault_env
from mrta_zenoh.identity import OBSERVER
from mrta_zenoh.lockstep.ended import EndedWatch
from mrta_zenoh.lockstep.protocol import DEFAULT_TIMEOUT
from mrta_zenoh.node import Node, NodeTime
from mrta_zenoh.processes import Child, ProcessGroup, mrta_argv
from mrta_zenoh.seeds import SEED_ENV
from mrta_zenoh.tasks.messages import INTAKE, Op
from mrta_zenoh.tasks.server import TOKEN as INTAKE_TOKEN
from mrta_zenoh.toolchain.launchfile import LaunchEvaluator, NodeSpec, check_executables
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.toolchain.runner import start_nodes

from ..live.api import Refresh, attach
from ..live.entities import Serving
from ..live.state import Supervisor
from . import roles, secured
from .analysis import analyse, folder_state
from .hosting import host_nodes, hosted_crash
from .hook import MissionOptions, MissionRun, instance_folder, resolve
from .overrides import apply_overrides
from .run_watch import (RECORDER, Readiness, RunWatch, check_simulator_end, crashed_itself,
                        ended_early)
from .summary import Summary

log = logging.getLogger("mrta.mission")


Progress = Callable[[float, Supervisor, "Failure | None", "float | None"], None]


def run_mission(options: MissionOptions, *, stop: threading.Event | None = None,
                progress: Progress | None = None) -> tuple[MissionRun, Summary]:
    """Run the mission; `progress(now, supervisor, failure, failed_at)` is called about 4 times
    a wall second while it runs (the live view). Without one, this process's supervisor hears
    only the application's task news, which ends the run once every task is done (the
    recorder's own supervisor keeps the picture: live/api.attach). Returns what ran and its
    summary."""
    reg = Registry()
    run = resolve(options, reg)  # its faults checked against the installed package's robots
    if not run.mission.launch:
        raise ConfigError(f"mission {run.mission.name!r} names no launch file")
    if options.overrides and options.instance is None:  # installed packages are never written
        raise ConfigError("--override sets parameters of the packages a run derives from its "
                          "--instance: give one (an experiment copies the package instead)")
    created = not options.output.exists()
    options.output.mkdir(parents=True, exist_ok=True)
    try:
        with output_lock(options.output):
            if options.instance is not None:
                # the packages this run reads, not every architecture's (tens of MB at size)
                run.mission.derive(options.instance, instance_folder(options), run.arch.name)
                reg = Registry([instance_folder(options)] + reg_path())
                run = resolve(options, reg)
                if options.overrides and \
                        instance_folder(options) not in run.package.path.parents:
                    raise ConfigError(f"--override: the instance derives no "
                                      f"{run.package.name!r} package to set it in")
                apply_overrides(run.package.path, options.overrides)  # the run's own copy
            run = roles.with_random_drawn(run)  # from the instance's own numbers
            return _run_in(run, reg, stop, progress, folder_state(options.output))
    except ConfigError:
        # a refused run (a bad instance, a bad override) leaves no empty folder behind (issue
        # 51, the newcomer's list); a folder that was there, or holds anything, stays
        if created:
            with contextlib.suppress(OSError):
                options.output.rmdir()
        raise


def reg_path() -> list[Path]:
    return [Path(p) for p in os.environ.get("MRTA_PACKAGE_PATH", "").split(os.pathsep) if p]


LOCK_FILE = ".mrta-run.lock"


@contextlib.contextmanager
def output_lock(output: Path):
    """Hold `output` for this run: a second run writing into the same folder would interleave
    two recordings into one corrupt run.mcap and two summaries into one, and both would exit 0.
    An advisory lock (flock) on a hidden file: released by the kernel when this process ends,
    however it ends, so a killed run never leaves the folder locked. The file is removed when
    the run ends (a killed run leaves it, unlocked); a run that opened it just before — and so
    locked a file no longer in the folder — opens the folder's file again."""
    import fcntl
    path = output / LOCK_FILE
    while True:
        f = path.open("a+")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            holder = f.read().strip() or "?"
            f.close()
            raise ConfigError(f"{output} is in use by another run (pid {holder}): choose "
                              "another --output") from None
        try:
            if os.stat(path).st_ino == os.fstat(f.fileno()).st_ino:
                break
        except FileNotFoundError:
            pass
        f.close()
    try:
        f.seek(0)
        f.truncate()
        f.write(str(os.getpid()))
        f.flush()
        yield
    finally:
        path.unlink(missing_ok=True)  # still locked: nobody else holds this file meanwhile
        f.close()


def _run_in(run: MissionRun, reg: Registry,
            stop: threading.Event | None, progress: Progress | None,
            before: dict[str, tuple[int, int, int]]) -> tuple[MissionRun, Summary]:
    options, output, faults = run.options, run.options.output, run.faults
    launch_args = {"speed": str(options.speed), "seed": str(options.seed),
                   "sim_args": f"--duration {options.duration}"
                               + (f" --snapshot {output / 'world.png'} --snapshot-label "
                                  f"{shlex.quote(run.arch.title)}" if options.plots else "")
                               + (" --lockstep" if options.lockstep else "")
                               + (f" --lockstep-timeout {host_timeout(options.agents_per_process)}"
                                  if options.lockstep and options.agents_per_process > 1
                                  else "")}
    launch = run.package.path / "launch" / run.mission.launch
    nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(launch, launch_args)
    check_executables(nodes)
    check_end(nodes, launch, run.arch.processes)
    check_seeds(nodes, options.seed)
    hosted: dict[str, str] = {}  # robot → its host's node name (agent hosts)
    if options.agents_per_process > 1:
        nodes, hosted = host_nodes(nodes, run.robots, options.agents_per_process,
                                   output / "hosts")
    rendezvous = options.rendezvous or private_rendezvous()
    routed = len(run.robots) >= ROUTER_FROM
    client = ["--mode", "client", "--connect", rendezvous] if routed else []
    # a secured fleet (--secure): every process a client of the fleet's router, each with its
    # own certificate (secured.py)
    fleet = None if options.secure is None else secured.fleet(
        options.secure, run.robots, run.arch.processes, intake_path(run) is not None)
    for n in nodes:
        n.args = [*n.args, *(client if fleet is None else fleet.args(
            secured.SIMULATOR if n.required else n.name if n.name in run.arch.processes
            else n.name.split("/")[0]))]
    members: set[str] = set()
    # which members' processes ended, told to the simulator by a file, not the bus (a token
    # under a member's name outlives its process when a forger declares it too: lockstep/ended.py)
    ended_dir = tempfile.TemporaryDirectory(prefix="mrta-lockstep-") if options.lockstep else None
    if ended_dir is not None:  # only the run's processes take part: a stranger's token is refused
        sim_node = next(n for n in nodes if n.required)
        members = {*run.robots, *hosted.values(), INTAKE,
                   *(n.name for n in nodes if n.name in run.arch.processes)}
        sim_node.args = [*sim_node.args, "--lockstep-members", ",".join(sorted(members)),
                         "--lockstep-ended", str(Path(ended_dir.name) / "ended")]
    # every process of the run: the run's seed and exactly the run's faults (none inherited
    # from this process's own environment), which each injects at its simulated time
    env = {k: v for k, v in os.environ.items() if k not in (FAULTS_ENV, RETIRED_CRASH_ENV)}
    lease = run_lease(options.lockstep)
    env.update(MRTA_RENDEZVOUS=rendezvous, PYTHONUNBUFFERED="1", **{SEED_ENV: str(options.seed)},
               **{LEASE_ENV: f"{lease:g}"}, **fault_env(faults))
    if options.instance is not None:  # the children find the run's own packages first
        env["MRTA_PACKAGE_PATH"] = os.pathsep.join(map(str, [instance_folder(options)]
                                                       + reg_path()))
    failure = faults.primary
    failed_at: float | None = None
    t_wall0 = time.monotonic()
    with ProcessGroup(env) as hub, \
            Node(_meeting(hub, rendezvous, routed, fleet, lease), OBSERVER, time=NodeTime.SIM,
                 stop=stop) as node, \
            ProcessGroup(env) as group, contextlib.ExitStack() as live:
        bus, clock, stop = node.bus, node.clock, node.stop
        # where the run's bus is, once it is up: for `mrta echo --connect`, a debugger, a
        # test's forger
        log.info("the run's processes meet at %s", rendezvous if fleet is None
                 else f"{fleet.endpoint} (the secured fleet's router)")
        ready = live.enter_context(Readiness(bus, run.robots))
        intake_up = threading.Event()
        live.enter_context(bus.watch_liveliness(INTAKE_TOKEN, lambda _k, alive: alive
                                                and intake_up.set()))
        # every process's token from before the first one starts: a loss is a disturbance
        watch = live.enter_context(RunWatch(bus, run.arch, clock))
        # the recording: the bus, the scene and the supervisor's channels, readable by Foxglove;
        # with a Foxglove port the same channels are also served live
        sup = Supervisor(run.arch_model, run.app, 0.0, unattended_after=30.0,
                         duplicate_after=5.0, watch=run.mission.task_watch(run),
                         quiet=progress is None,  # nobody to tell its alarms to
                         serving=Serving(run.arch))
        for h in attach(sup, bus, clock, shown=progress is not None):
            live.callback(h.close)
        recorder = group.start(mrta_argv(*recorder_args(
            options, run.package.name,
            client if fleet is None else fleet.args(secured.RECORDER))), name="record")
        intake = _start_intake(run, group, client if fleet is None
                               else fleet.args(secured.INTAKE))
        children = _start_up(nodes, group, ready, intake_up if intake is not None else None,
                             stop)
        agents = {rid: next(c for c in children if c.name == hosted.get(rid)
                            or c.name.startswith(rid + "/")) for rid in run.robots}
        # the architecture's own processes (a dispatcher), by name: fault subjects as robots are
        named = {**agents, **{c.name: c for c in children if c.name in run.arch.processes}}
        if ended_dir is not None:
            live.callback(ended_dir.cleanup)
            live.enter_context(EndedWatch(Path(ended_dir.name) / "ended", {
                name: c.running for name, c in {**agents, **{c.name: c for c in children},
                                                INTAKE: intake}.items()
                if name in members and c is not None}))

        def struck(subject: str) -> bool:  # its injected crash struck: its process, or its host
            if subject in hosted:
                return hosted_crash(named.get(subject), subject)
            return crashed_itself(named.get(subject))

        def own_process(targets) -> list[str]:  # a host goes on when one of its robots crashes
            return [named[t].name for t in targets if t in named and t not in hosted]

        sim = next(c for c, n in zip(children, nodes) if n.required)  # the launch's end
        # a crash the run injected may strike before this runner saw everyone up (a busy
        # machine, lockstep at full speed): the crashed subject is no start-up failure
        def injected() -> set[str]:
            itself = {r: struck(r) for r in named}
            return {t for t in roles.crash_targets(faults, itself) if itself.get(t)}

        ready.wait(lambda: not set(ready.presence.missing()) - injected(), "the robots' agents",
                   group, stop, ignore=lambda: own_process(injected()),
                   progress=lambda: len(ready.presence.missing()))
        # start-up, read by benchmarks/hosts.py (one process per robot against hosts)
        log.info("%s: every robot's agent up, %.1f s after the run's processes began",
                 AGENTS_UP, time.monotonic() - t_wall0)
        ready.wait(ready.clock.is_set, "the simulator", group, stop,
                   ignore=lambda: own_process(injected()))
        failed_at = _watch(sim, sup, clock, failure, stop, progress,
                           early_from=_ends_early_from(run) if intake is not None else 0.0)
        watch.end()
        live.close()
        interrupted = None
        by_sigint = not stop.is_set() and sim.wait(30) in (-signal.SIGINT, 128 + signal.SIGINT)
        if stop.is_set() or by_sigint:
            # Ctrl-C: the terminal sends SIGINT to the children as well, and the simulator may
            # end by it before this process sees its own. Their ends are no failures. The
            # recording so far is whole once the recorder has written it out: the summary
            # covers the run up to then and says it was interrupted (issue 51, the newcomer's
            # list: a Ctrl-C'd demo left none); the exit is 130 after Ctrl-C, 0 after SIGTERM
            # (cli.main._exit_code)
            group.interrupted()
            interrupted = "Ctrl-C" if by_sigint or lifecycle.interrupted_by_user() else "SIGTERM"
        else:
            check_simulator_end(sim)
        group.stop_all(later=[recorder], later_grace=RECORDER_GRACE)
        # the crashed subjects: those named (robots, the architecture's processes) and, for an
        # @first crash, the robot that crashed itself
        targets = roles.crash_targets(faults, {r: struck(r) for r in agents})
        ours = set(named) | set(hosted.values()) | {INTAKE}  # the run's processes
        # an interrupted run's processes stopped as asked: no disturbance, no crash
        disturbances = [] if interrupted else \
            watch.disturbances(lambda p: p in targets and struck(p), ours)
        strangers = watch.strangers(ours)
        if watch.unseen:
            log.info("this runner's own link to the run's router closed and reopened while the "
                     "run was on: %d token loss(es) seen meanwhile were its own blindness, not "
                     "the processes' (no disturbance)", watch.unseen)
        crashed = [] if interrupted else group.failed(ignore=own_process(targets))
        if crashed:  # a dispatcher or recorder SIGKILLed from outside: what can be known
            for c in crashed:
                log.error("%s %s:\n%s", c.name, c.describe_exit(), c.tail(10))
            process = {id(recorder): RECORDER, **{id(c): rid for rid, c in agents.items()},
                       **{id(c): name for name, c in named.items()}}
            disturbances = ended_early(disturbances, {
                process.get(id(c), c.name): c.describe_exit() for c in crashed}, clock.now())
    summary = analyse(run, failure, failed_at, time.monotonic() - t_wall0, before, disturbances,
                      strangers, interrupted)
    return run, summary


def _start_up(nodes: list[NodeSpec], group: ProcessGroup, ready: Readiness,
              intake_up: threading.Event | None, stop: threading.Event) -> list[Child]:
    """Start the launch's nodes beside the recorder and the task intake (`intake_up`: its
    token, None when the run has none), already started; their children, in `nodes`' order.

    At once, not one after the other: the robots' processes (agents, hosts, a dispatcher)
    start with the recorder and the intake — each is a process that spends its start-up
    importing and reading its files, and 100 robots' host used to begin only after the
    recorder was up (issue 47: agents up 190 s after the command). What must come first is
    read from tokens, never from time or log lines: the simulator — the launch's required
    node, whose lockstep clock starts once every robot's agent has joined (--wait-robots) —
    starts once the recorder, and the intake if any, are up, so the recording covers the run
    from its first step and every change of the intake enters at a step boundary."""
    first = start_nodes(group, [n for n in nodes if not n.required])
    ready.wait(ready.recorder.is_set, "the recorder", group, stop)
    if intake_up is not None:
        ready.wait(intake_up.is_set, "the task intake", group, stop)
    last = iter(start_nodes(group, [n for n in nodes if n.required]))
    others = iter(first)
    return [next(last) if n.required else next(others) for n in nodes]


def recorder_args(options: MissionOptions, package: str, client: list[str]) -> list:
    """The run's recorder, on simulated time: `mrta view` (the bus and the channels a viewer
    draws; served live with a Foxglove port), or, with `recording` "bus" and no port, `mrta
    record` — the bus and every liveliness change, which is all the analysis reads (recording.
    read_recording drops the derived channels), without the view's supervisor, scene and their
    imports: ≈ 1.5 of a 5 / 5 study run's ≈ 4 recorder CPU-s (benchmarks/README.md, "The
    study's runs"). Both announce the same recorder token and drain the same way."""
    out = options.output / "run.mcap"
    if options.recording == "bus" and options.foxglove_port is None:
        return ["record", "--sim-time", "--output", out, *client]
    view = ["view", package, "--sim-time", "--output", out, *client]
    return view + (["--port", str(options.foxglove_port)] if options.foxglove_port is not None
                   else ["--no-server"])


def host_timeout(per_host: int) -> float:
    """The lockstep timeout (wall s) when robots run `per_host` to a process: a host answers a
    step once each of its robots has ticked, one after the other, so a step where every robot
    decides costs it K robots' decisions — at 100 robots × 100 tasks CBBA's first bundles took
    ≈ 0.5 s each, ≈ 50 s for the host, and the default 30 s gave it up and the run went on
    without its robots (benchmarks/README.md, agent hosts). A dead host is not waited for
    either way (its token goes with it)."""
    return DEFAULT_TIMEOUT * per_host


def _start_intake(run: MissionRun, group: ProcessGroup, client: list[str]) -> Child | None:
    """The run's task intake (`mrta task serve`, a lockstep participant: mrta_zenoh.tasks) when
    the run takes tasks at run time: it is reachable (`--rendezvous`) or its instance schedules
    changes (a run repeated from its summary). None otherwise: every other run is as before."""
    path = intake_path(run)
    if path is None:
        return None
    closed = run.arch.submitted_refusal()
    return group.start(mrta_argv("task", "serve", "--instance", str(path), "--sim-time",
                                 *(("--closed", closed) if closed else ()), *client),
                       name=INTAKE)


def intake_path(run: MissionRun) -> Path | None:
    """The instance a task intake serves, when the run takes tasks at run time (_start_intake);
    None when it does not."""
    options = run.options
    path = options.instance or run.mission.instance_file(run)
    if path is None:
        return None
    if not reachable(options):
        loaded = instances.load(path)
        if not loaded.kind.schedule(loaded.doc):
            return None
    return path


def reachable(options: MissionOptions) -> bool:
    """Whether other terminals may submit tasks to the run (it then has an intake and goes on
    to its duration): on a rendezvous they reach (`--rendezvous`), or on a secured fleet that
    has a submitter (`mrta secure init --submitter NAME` wrote the intake's certificate,
    tasks.json5): `mrta task submit --as NAME --zenoh-config FLEET/NAME.json5` reaches it
    through the fleet's router."""
    return options.rendezvous is not None or (
        options.secure is not None
        and secured.Fleet(options.secure).config(secured.INTAKE).is_file())


def _ends_early_from(run: MissionRun) -> float | None:
    """From when a run with a task intake may end once nothing is left to serve (None: it goes
    on to its duration). A reachable run (`reachable`) goes on: more may come from other
    terminals. A run replaying its instance's schedule (a summary's `submitted`) may end once
    every scheduled change has entered — a task it cancels is then settled (the application's
    TaskWatch says so) — unless the schedule submits a task: the live supervisor knows the
    instance's tasks, not the submitted ones, so it could not tell that they were served."""
    if reachable(run.options):
        return None
    path = run.options.instance or run.mission.instance_file(run)
    loaded = instances.load(path)
    changes = loaded.kind.schedule(loaded.doc)
    if any(c.op == Op.SUBMIT for c in changes):
        return None
    return max((c.at for c in changes), default=0.0)


AGENTS_UP = "agents up"  # the start-up line's mark

# From this many robots a run's processes meet through a router of their own (`mrta router` on
# the run's rendezvous, every process its client) instead of in a peer mesh: the mesh's N + 3
# processes keep (N + 3)² links, whose keep-alives alone cost every process CPU in proportion
# to N — ≈ 2 % of a core each at 50 robots while idle, a whole core in all — so lockstep ran
# 50 robots at 0.02× real time, against 0.5× through a router (benchmarks/README.md, team sizes).
ROUTER_FROM = 20


def _meeting(hub: ProcessGroup, rendezvous: str, routed: bool,
             fleet: secured.Fleet | None = None, lease: float | None = None) -> BusOptions:
    """The supervisor's bus options: the run's peer mesh, or (`routed`) a client of the run's
    router, started in `hub` and up once its endpoint accepts connections — or, on a secured
    `fleet`, a client of the fleet's router under the supervisor's certificate. `lease`: the
    run's (run_lease)."""
    if fleet is not None:
        fleet.start_router(hub)
        return fleet.bus(secured.SUPERVISOR)
    if not routed:
        return BusOptions(rendezvous=rendezvous, lease=lease)
    secured.start_router(hub, [], rendezvous, "the run's router")  # on $MRTA_RENDEZVOUS
    return BusOptions(mode="client", connect=[rendezvous], lease=lease)


def run_lease(lockstep: bool) -> float:
    """The Zenoh lease of every process of a run (bus/options.py, LEASE), given them as
    $MRTA_LEASE: in lockstep, lockstep's wait for a live participant (DEFAULT_TIMEOUT, 30 s).
    The README's 20-robot walkthrough at load 25 exited 1 because the recorder, starved of CPU
    for more than the 3 s default, was dropped from the bus and missed a delivery (issue 51):
    the run is now slower there, not failed. Nothing real is hidden: a killed process's socket
    closes at once, whatever the lease; a stopped agent or simulator is waited for by lockstep
    anyway, and past 30 s it is given up and the run not called exact; a stopped recorder
    holds the reliable publishers back (losing none of what the summary reads) for as long as
    a slow reader is waited for (SLOW_READER_US, 30 s), and past that its link goes and the
    run is incomplete, as before. Without lockstep the outcome depends on timing, and a
    process silent past the default 3 s is reported: the default stays. $MRTA_LEASE set by
    the caller wins (tests stop a process past a short one)."""
    if os.environ.get(LEASE_ENV, "").strip():
        return lease_from_env()
    return DEFAULT_TIMEOUT if lockstep else LEASE


def check_end(nodes: list[NodeSpec], launch: Path, processes: tuple[str, ...] = ()) -> None:
    """A run ends when its launch's required node (the simulator) ends, as `mrta launch`'s
    does: a launch with none is refused before anything starts, naming the file. So is one
    that starts none of the architecture's own `processes` (a dispatcher): its robots would
    wait for it the whole run, idle (issue 51: a hand-made central package)."""
    if not any(n.required for n in nodes):
        raise ConfigError('no node is required="true": a mission run ends when its launch\'s '
                          "required node (the simulator) ends", file=str(launch))
    missing = [p for p in processes if p not in {n.name for n in nodes}]
    if missing:
        raise ConfigError(f"no node named {missing[0]}: the architecture's own process, which "
                          "its robots wait for", file=str(launch))


def check_seeds(nodes: list[NodeSpec], seed: int) -> None:
    """Every process of a run draws from the run's seed, which this runner hands to all of them
    ($MRTA_SEED): a launch file that gives a node another one — `--seed` in its args, or a
    $MRTA_SEED of its own — is refused before anything starts, naming the node."""
    for n in nodes:
        given = [a.split("=", 1)[1] for a in n.args if a.startswith("--seed=")]
        given += [b for a, b in zip(n.args, n.args[1:]) if a == "--seed"]
        given += [n.env[SEED_ENV]] if SEED_ENV in n.env else []
        for value in given:
            if value.strip() != str(seed):
                raise ConfigError(f"node {n.name} is given seed {value!r}, but the run's seed is "
                                  f"{seed}: the runner hands every node the run's seed "
                                  f"(${SEED_ENV}); leave the seed out of the launch file",
                                  file=n.file or None, line=n.line)


# wall s the recorder has to write out what it holds once every other process has ended: on a
# busy machine it may be ~300,000 samples behind (20 robots at --speed 0); killed sooner, the
# recording missed the mission's end (the newcomer's `--no-plots` run, issue 51)
RECORDER_GRACE = 120.0
END_MARGIN = 1.0  # simulated s the simulator runs on once nothing is left to serve: the recording
                  # then covers the end (run_watch.END_SLACK), however late the runner saw it


def _watch(sim: Child, sup: Supervisor, clock: SimClock, failure: Failure | None,
           stop: threading.Event, progress: Progress | None,
           early_from: float | None = 0.0) -> float | None:
    """Follow the run until the simulator ends — at its duration, or stopped here END_MARGIN
    after the application's task watch said nothing is left to serve, every task done,
    missed or cancelled (Mission.task_watch) — not before `early_from` (simulated s; None:
    never, _ends_early_from); return when `failure` struck (each process injects its own
    faults, at their simulated times)."""
    failed_at = None
    all_done: float | None = None
    refresh = Refresh(sup, clock, sim_time=True)
    while sim.running() and not stop.is_set():
        stop.wait(0.25)
        now = refresh()
        if failure and failed_at is None and now >= failure.at:
            failed_at = failure.at
        if progress is not None:
            progress(now, sup, failure, failed_at)
        if early_from is not None and now >= early_from and all_done is None \
                and sup.all_done():
            all_done = now
        if all_done is not None and now >= all_done + END_MARGIN:
            # the time the summary reports (ended_at) is when the work was seen over, not
            # when the runner, polling a faster-than-real-time run, stops the simulator
            log.info("nothing was left to serve by t=%.1f (the mission's task watch: every task "
                     "done or missed): ending the run", all_done)
            sim.signal(signal.SIGTERM)
            all_done = math.inf  # asked once
    return failed_at
