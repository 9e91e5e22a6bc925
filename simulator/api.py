"""Run the simulator: what `mrta sim` does, callable from Python and tests."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import logging
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from mrta_zenoh import instances, keys
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.clock import run_id as new_run_id
from mrta_zenoh.errors import ConfigError, MrtaRuntimeError
from mrta_zenoh.limits import COORDINATE
from mrta_zenoh.lockstep.barrier import Barrier
from mrta_zenoh.lockstep.ended import read_ended
from mrta_zenoh.lockstep.protocol import DEFAULT_TIMEOUT, PARTICIPANT
from mrta_zenoh.node import Node
from mrta_zenoh.presence import RobotPresence
from mrta_zenoh.ros2.types import SONAR_TYPES
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.yamlfile import plural

from .engine import Simulation
from .node import RunStats, SimNode
from .ros2 import Ros2Driver
from .robot_model import RobotModel
from .secure_role import SIMULATOR_ROLE
from .world import Pose, World, load_world

log = logging.getLogger("mrta.sim")


def resolve_world(spec: str) -> Path:
    """A path, or the name of a world a registered package ships (`patrol`)."""
    path = Path(spec)
    if path.exists():
        return path
    return Registry().world(spec)


def parse_robot(spec: str) -> tuple[str, str | Pose | None]:
    """`robot1`, `robot1=home0` (a named start) or `robot1=x,y,theta_degrees`."""
    rid, sep, rest = spec.partition("=")
    rid = keys.normalize_robot_id(rid)
    if not sep:
        return rid, None
    parts = rest.split(",")
    if len(parts) == 1:
        return rid, rest.strip()
    if len(parts) not in (2, 3):
        raise ConfigError(f"--robot {spec!r}: expected ID, ID=START or ID=x,y[,theta_degrees]")
    try:
        vals = [float(p) for p in parts] + ([0.0] if len(parts) == 2 else [])
    except ValueError:
        raise ConfigError(f"--robot {spec!r}: x, y and theta must be numbers") from None
    if not all(math.isfinite(v) for v in vals):
        raise ConfigError(f"--robot {spec!r}: x, y and theta must be finite")
    for axis, v in zip("xy", vals):
        problem = COORDINATE.problem(v)
        if problem is not None:
            raise ConfigError(f"--robot {spec!r}: {axis} {problem}")
    return rid, Pose.from_degrees(*vals)


def place_robots(world: World, specs: list[tuple[str, str | Pose | None]]) -> dict[str, Pose]:
    """Start poses: explicit, a named start, the start named like the robot, or the next free one."""
    ids = [rid for rid, _ in specs]
    dupes = {r for r in ids if ids.count(r) > 1}
    if dupes:
        raise ConfigError(f"robot {sorted(dupes)[0]!r} is given more than once")
    used: set[str] = set()
    poses: dict[str, Pose] = {}
    for rid, spec in specs:
        if isinstance(spec, str):
            if spec not in world.starts:
                raise ConfigError(f"--robot {rid}={spec}: the world has no start named {spec!r} "
                                  f"(it has: {', '.join(world.starts) or 'none'})")
            poses[rid] = world.starts[spec]
            used.add(spec)
        elif isinstance(spec, Pose):
            poses[rid] = spec
        elif rid in world.starts:
            poses[rid] = world.starts[rid]
            used.add(rid)
    for rid, spec in specs:
        if rid in poses:
            continue
        free = [n for n in world.starts if n not in used and n not in ids]
        if not free:
            raise ConfigError(f"no start pose left for {rid}: give --robot {rid}=x,y,theta")
        poses[rid] = world.starts[free[0]]
        used.add(free[0])
    return {rid: poses[rid] for rid in ids}


@dataclass(frozen=True)
class SimOptions:
    """Everything `mrta sim` is asked to do, checked once when built (bad values are bad input,
    exit 2, before anything opens): the verb builds one from its options, a Python caller
    directly. `robots`: `ID`, `ID=START` or `ID=x,y[,theta_degrees]` (parse_robot); `ros2`: the
    robots served as ROS 2 robots instead of on our keys; `markers`: an instance file whose
    tasks the snapshot marks (with_instance_markers)."""

    world: str
    robots: tuple[str, ...]
    speed: float = 1.0
    seed: int = 0
    duration: float | None = None
    snapshot: Path | None = None
    snapshot_label: str | None = None
    rear_sonars: bool = False
    wait_robots: float | None = None
    lockstep: bool = False
    lockstep_timeout: float = DEFAULT_TIMEOUT
    lockstep_members: tuple[str, ...] | None = None
    lockstep_ended: Path | None = None
    ros2: tuple[str, ...] = ()
    ros2_domain: int = 0
    ros2_sonar_type: str = "pointcloud"
    ros2_distro: str = "jazzy"
    markers: Path | None = None

    def __post_init__(self) -> None:
        # sequences given as lists stay usable, and the options stay hashable
        object.__setattr__(self, "robots", tuple(self.robots))
        object.__setattr__(self, "ros2", tuple(self.ros2))
        if self.lockstep_members is not None:
            object.__setattr__(self, "lockstep_members", tuple(self.lockstep_members))
            if not self.lockstep:
                raise ConfigError("--lockstep-members goes with --lockstep: it names who may "
                                  "take part in lockstep")
        if self.lockstep_ended is not None and self.lockstep_members is None:
            raise ConfigError("--lockstep-ended goes with --lockstep-members: it names which "
                              "members' processes have ended")
        if self.speed < 0 or not math.isfinite(self.speed):
            raise ConfigError(f"--speed must be a finite number ≥ 0, got {self.speed}")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise ConfigError(f"--duration must be a positive finite number, got {self.duration}")
        if not self.robots:
            raise ConfigError("give at least one --robot")
        if self.ros2 and self.lockstep:
            raise ConfigError("--ros2 and --lockstep exclude each other: a ROS 2 robot's driver "
                              "and bridge run on their own time, so its runs could not be "
                              "reproduced")
        if self.ros2_sonar_type not in SONAR_TYPES:
            raise ConfigError(f"--ros2-sonar-type {self.ros2_sonar_type!r}: expected one of "
                              f"{', '.join(SONAR_TYPES)}")


def with_instance_markers(world: World, instance: Path) -> World:
    """The world with an instance's tasks as markers beside its own (`--markers FILE`): an
    application's package states where its tasks are once, in its instance, and the
    simulator reads them through the core's instance registry (InstanceKind.task_positions),
    knowing no application."""
    loaded = instances.load(instance)
    return dataclasses.replace(world, markers={**world.markers,
                                               **loaded.kind.task_positions(loaded.doc)})


def run_simulator(options: SimOptions, bus_options: BusOptions,
                  stop: threading.Event | None = None) -> RunStats:
    """Load the world, place the robots and run the simulation on the bus until the duration
    (simulated) is reached or `stop` is set; the run's statistics."""
    o = options
    if o.snapshot is not None and not Path(o.snapshot).parent.resolve().is_dir():
        raise ConfigError(f"--snapshot {o.snapshot}: folder {Path(o.snapshot).parent} does not "
                          "exist")
    world = load_world(resolve_world(o.world))
    if o.markers is not None:
        world = with_instance_markers(world, Path(o.markers))
    robots = place_robots(world, [parse_robot(s) for s in o.robots])
    ros2_ids = [keys.normalize_robot_id(r) for r in o.ros2]
    for rid in ros2_ids:
        if rid not in robots:
            raise ConfigError(f"--ros2 {rid}: not one of the simulated robots "
                              f"({', '.join(robots)})")
    for note in world.notes:
        log.info("%s: %s", world.source, note)
    sim = Simulation(world, robots, RobotModel(rear_sonars=o.rear_sonars), seed=o.seed,
                     record_trails=o.snapshot is not None)
    # tells followers a restarted simulator from this run, and the speed that bounds its time
    run_id = new_run_id(o.speed)
    node = Node(bus_options, SIMULATOR_ROLE, stop=stop)  # a certificate not the simulator's: refused
    with node, contextlib.ExitStack() as resources:
        bus, stop = node.bus, node.stop
        # lockstep counts the commands it receives from the start: an agent waiting for the
        # run may already have sent some (its clock watchdog's stop), and claims them
        barrier = resources.enter_context(Barrier(
            bus, run_id, o.lockstep_timeout, members=None if o.lockstep_members is None
            else frozenset(o.lockstep_members), ended=None if o.lockstep_ended is None
            else functools.partial(read_ended, Path(o.lockstep_ended)))) \
            if o.lockstep else None
        driver = (lambda command: Ros2Driver(bus, ros2_ids, command, domain=o.ros2_domain,
                                             distro=o.ros2_distro,
                                             sonar_type=o.ros2_sonar_type)
                  ) if ros2_ids else None
        node = resources.enter_context(SimNode(sim, bus, o.speed, run_id=run_id, ros2=driver))
        if o.wait_robots is not None and not wait_for_robots(bus, list(robots), o.wait_robots,
                                                             stop):
            return node.stats
        if barrier is not None:
            barrier.settle()  # the participants already up are heard
            if o.wait_robots is not None:
                # every robot's agent in step from step 0: one that joins later starts its
                # first tick at whatever time the others had reached, and the same seed gave
                # two different runs (the first tick at 0.0 or 0.1, depending on load)
                expected = set(robots) - set(ros2_ids)
                deadline = time.monotonic() + o.wait_robots
                # a robot answered for by an agent host (lockstep SPEAKS) counts as joined
                while not expected <= barrier.voiced() and not stop.is_set() \
                        and time.monotonic() < deadline:
                    stop.wait(0.05)
                missing = sorted(expected - barrier.voiced())
                if barrier.participants and missing:
                    raise MrtaRuntimeError(
                        f"lockstep: {', '.join(missing)} did not join within {o.wait_robots:g} s "
                        "(--wait-robots): its agent runs without --sim-time, or an "
                        f"access-control configuration denies its {PARTICIPANT}/<robot> token; "
                        "a run without it would not be reproducible")
            if o.wait_robots is not None and not barrier.participants:
                raise MrtaRuntimeError(
                    f"lockstep: no participant after {o.wait_robots:g} s although "
                    f"{plural(len(robots), 'robot')} {'was' if len(robots) == 1 else 'were'} "
                    "expected (--wait-robots): the agents "
                    "run without --sim-time, or are not up, or an access-control configuration "
                    f"denies their {PARTICIPANT}/<robot> tokens to this simulator (docs/"
                    "security.md); running without them would not be lockstep")
        if o.snapshot is not None:  # also when the run fails: the picture shows how far it got
            # which robots have no process left, taken as the clock stops — before it says it
            # ended, on which every agent stops (then every robot would look gone)
            presence = resources.enter_context(RobotPresence(bus, list(robots)))
            gone: list[frozenset[str]] = []
            resources.callback(lambda: _snapshot(sim, o.snapshot, o.snapshot_label,
                                                 gone[0] if gone else
                                                 frozenset(presence.gone())))
        resources.enter_context(bus.declare_token(f"{keys.CLOCK_SOURCE_TOKEN}/{run_id}"))
        log.info("ready: %s in %s (%d walls), speed %s, seed %d%s",
                 plural(len(robots), "robot"), world.name, len(world.walls),
                 o.speed if o.speed else "max", o.seed,
                 f", lockstep with {plural(len(barrier.participants), 'participant')}"
                 if barrier is not None else "")
        stats = node.run(stop, o.duration, barrier)
        if o.snapshot is not None:
            gone.append(frozenset(presence.gone()))
        # the run ends on purpose (its duration, a stop): said before its tokens go, so that
        # followers tell an end from a death (mrta_zenoh.clock.SimClock.ended)
        resources.enter_context(bus.declare_token(
            f"{keys.CLOCK_SOURCE_TOKEN}/{run_id}/{keys.CLOCK_SOURCE_ENDED}"))
    log.info("done: %.1f s simulated in %.1f s (%.1f× real time), %d commands",
             stats.sim_time, stats.wall_time, stats.real_time_factor, stats.commands)
    return stats


def _snapshot(sim: Simulation, path: Path, label: str | None, gone: frozenset[str]) -> None:
    from .snapshot import save_snapshot  # matplotlib (≈ 1.5 CPU-s to import): only for a picture
    save_snapshot(sim, path, label=label, gone=gone)
    log.info("snapshot written to %s", path)


def wait_for_robots(bus, robot_ids: list[str], timeout: float, stop: threading.Event) -> bool:
    """Block until every robot has a liveliness token under `robotN/**` (its agent is up), so the
    clock starts with every controller ready. False if stopped; a log line (and go on) after
    `timeout` wall seconds, so one robot that never comes cannot hold the world forever."""
    deadline = time.monotonic() + timeout
    with RobotPresence(bus, robot_ids) as presence:
        log.info("waiting for %s", ", ".join(robot_ids))
        while not presence.all_up():
            if stop.is_set():
                return False
            if time.monotonic() >= deadline:
                log.warning("still no process for %s after %.0f s: starting anyway",
                            ", ".join(presence.missing()), timeout)
                break
            presence.changed.wait(0.1)
            presence.changed.clear()
    return True
