"""`mrta sim`: a thin click wrapper over simulator.api.run_simulator (its options: SimOptions)."""

from __future__ import annotations


from pathlib import Path

import click

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import SEED_TYPE, OutputPath, bus_options, finite_float
from mrta_zenoh.lockstep.protocol import DEFAULT_TIMEOUT
from mrta_zenoh.ros2.types import SONAR_TYPES
from mrta_zenoh.seeds import SEED_ENV

from .api import SimOptions, run_simulator


@click.command()
@click.option("--world", required=True, metavar="FILE|NAME",
              help="A YAML world, a MobileSim .map, or the name of a world a registered package "
                   "ships.")
@click.option("--robot", "robots", multiple=True, required=True, metavar="ID[=x,y,theta]",
              help="A robot and its start: a pose (metres, degrees), a named start, or nothing "
                   "to use the start named like the robot or the next free one. Repeatable.")
@click.option("--speed", type=finite_float(min=0), default=1.0, show_default=True,
              help="Simulated seconds per wall second; 0 runs as fast as possible.")
@click.option("--seed", type=SEED_TYPE, default=0, show_default=True, envvar=SEED_ENV,
              help=f"The run's master seed (sensor noise), 0 to 2^63 − 1. Runners set ${SEED_ENV}.")
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many simulated seconds.")
@click.option("--snapshot", type=OutputPath(folder=False),
              help="On exit, write a PNG of the world with robots, sonar beams and trails.")
@click.option("--snapshot-label", metavar="TEXT",
              help="What ran the robots (an architecture), for the snapshot's title.")
@click.option("--rear-sonars", is_flag=True, help="Also simulate the 8 rear transducers.")
@click.option("--markers", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              metavar="INSTANCE",
              help="Mark this instance file's tasks on the snapshot (an application's package "
                   "names its instance: the tasks' places are stated there once).")
@click.option("--lockstep", is_flag=True,
              help="Advance only when every agent following simulation time is done with the "
                   "current step: runs reproducible whatever the machine's load.")
@click.option("--lockstep-timeout", type=finite_float(min=0, min_open=True),
              default=DEFAULT_TIMEOUT, show_default=True, metavar="SECONDS",
              help="Give up on a participant that holds its token but has not answered for "
                   "this long (wall time); it is reported, and rejoins when it answers. A "
                   "stopped or dead agent is not waited for: its token goes with its session "
                   "(at once, or after the 3 s Zenoh lease). Lower it only where no process "
                   "may be starved of CPU: a slow agent given up makes the run inexact.")
@click.option("--lockstep-members", metavar="NAME[,NAME…]",
              callback=lambda _c, _p, v: None if v is None else tuple(
                  n for n in (x.strip() for x in v.split(",")) if n),
              help="With --lockstep: take part only these participants (a mission's processes: "
                   "its agents, hosts, dispatcher, task intake); another's participant token is "
                   "a stranger's — refused, counted in lockstep/status, never waited for. "
                   "Default: anyone holding a participant token.")
@click.option("--lockstep-ended", type=click.Path(dir_okay=False, path_type=Path),
              metavar="FILE",
              help="With --lockstep-members: a file the run's runner appends the name of each "
                   "member whose process ended to (one a line; `mrta demo` writes it). Such a "
                   "member is not waited for, whatever participant token lives under its name "
                   "(on an open bus, anyone's).")
@click.option("--wait-robots", type=finite_float(min=0), metavar="SECONDS",
              help="Start the clock only once every robot has a process up (a liveliness token "
                   "under robotN/**), waiting at most this long.")
@click.option("--ros2", "ros2", multiple=True, metavar="ID",
              help="Serve this robot as a ROS 2 robot over rmw_zenoh (Twist in; Odometry and "
                   "sonar out), reachable only through `mrta ros2 bridge`. Repeatable.")
@click.option("--ros2-domain", type=click.IntRange(0, 232), default=0, show_default=True,
              envvar="ROS_DOMAIN_ID", show_envvar=True,
              help="ROS_DOMAIN_ID of the ROS 2 robots.")
@click.option("--ros2-sonar-type", type=click.Choice(sorted(SONAR_TYPES)), default="pointcloud",
              show_default=True, help="How the ROS 2 robots publish their sonar.")
@bus_options
def sim(bus_options: BusOptions, **options) -> None:
    """Simulate Pioneer 3-DX robots: cmd_vel in; clock, sonar, odom, ground_truth, bumper out."""
    run_simulator(SimOptions(**options), bus_options)  # each option is named as its field
