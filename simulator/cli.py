"""`mrta sim`: run the simulator for a world and a set of robots."""

from __future__ import annotations

import logging
import math
import threading
from pathlib import Path

import click

from mrta_zenoh import keys
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.cli.common import BadInput, bus_options, user_errors
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.paths import bundled_world

from .engine import Simulation
from .node import RunStats, SimNode
from .robot_model import RobotModel
from .snapshot import save_snapshot
from .world import Pose, World, load_world

log = logging.getLogger("mrta.sim")


def resolve_world(spec: str) -> Path:
    """A path, or the name of a world shipped in configs/worlds (`patrol`)."""
    path = Path(spec)
    if path.exists():
        return path
    bundled = bundled_world(spec)
    if bundled is not None:
        return bundled
    raise ConfigError(f"no such world file or bundled world: {spec!r}")


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


def main(world_spec: str, robot_specs: list[str], bus_opts: BusOptions, speed: float = 1.0,
         seed: int = 0, duration: float | None = None, snapshot: Path | None = None,
         rear_sonars: bool = False, stop: threading.Event | None = None) -> RunStats:
    with user_errors():
        if speed < 0 or not math.isfinite(speed):
            raise ConfigError(f"--speed must be a finite number ≥ 0, got {speed}")
        if not robot_specs:
            raise ConfigError("give at least one --robot")
        world = load_world(resolve_world(world_spec))
        robots = place_robots(world, [parse_robot(s) for s in robot_specs])
    for note in world.notes:
        log.info("%s: %s", world.source, note)
    sim = Simulation(world, robots, RobotModel(rear_sonars=rear_sonars), seed=seed,
                     record_trails=snapshot is not None)
    with user_errors(), stop_on_signals(stop) as stop, open_bus(bus_opts) as bus:
        node = SimNode(sim, bus, speed)
        with bus.declare_token(keys.SIMULATOR_TOKEN):
            log.info("ready: %d robots in %s (%d walls), speed %s, seed %d", len(robots),
                     world.name, len(world.walls), speed if speed else "max", seed)
            try:
                stats = node.run(stop, duration)
            finally:
                node.close()
                if snapshot is not None:
                    save_snapshot(sim, snapshot)
                    log.info("snapshot written to %s", snapshot)
    log.info("done: %.1f s simulated in %.1f s (%.1f× real time), %d commands",
             stats.sim_time, stats.wall_time, stats.real_time_factor, stats.commands)
    return stats


@click.command()
@click.option("--world", "world_spec", required=True, metavar="FILE|NAME",
              help="A YAML world, a MobileSim .map, or a bundled world name (patrol).")
@click.option("--robot", "robots", multiple=True, required=True, metavar="ID[=x,y,theta]",
              help="A robot and its start: a pose (metres, degrees), a named start, or nothing "
                   "to use the start named like the robot or the next free one. Repeatable.")
@click.option("--speed", type=float, default=1.0, show_default=True,
              help="Simulated seconds per wall second; 0 runs as fast as possible.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed for sensor noise.")
@click.option("--duration", type=float, help="Stop after this many simulated seconds.")
@click.option("--snapshot", type=click.Path(dir_okay=False, path_type=Path),
              help="On exit, write a PNG of the world with robots, sonar beams and trails.")
@click.option("--rear-sonars", is_flag=True, help="Also simulate the 8 rear transducers.")
@bus_options
def sim(world_spec: str, robots: tuple[str, ...], speed: float, seed: int,
        duration: float | None, snapshot: Path | None, rear_sonars: bool,
        bus_options: BusOptions) -> None:
    """Simulate Pioneer 3-DX robots: cmd_vel in; clock, sonar, odom, ground_truth, bumper out."""
    logging.getLogger("mrta.sim").setLevel(logging.INFO)
    if not logging.getLogger().handlers:
        logging.basicConfig(format="%(levelname)s %(name)s: %(message)s")
    if duration is not None and duration <= 0:
        raise BadInput(f"--duration must be positive, got {duration}")
    main(world_spec, list(robots), bus_options, speed, seed, duration, snapshot, rear_sonars)
