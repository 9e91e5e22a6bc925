"""`mrta ros2 bridge | graph`: thin click wrappers over mrta_zenoh.ros2.bridge and .graph.

Two conventions of ROS 2 users, kept by every command here:

* `--domain` defaults to `$ROS_DOMAIN_ID` (0 when unset), as in every ROS 2 tool;
* `--connect` without `--mode` means client mode: a robot runs rmw_zenohd, a router that does
  not broker between peers (`peers_failover_brokering: false`) while its nodes listen on the
  robot's localhost only — a peer connected to it hears nothing of them (0 samples, 0 tokens,
  measured), a client gets everything routed. `--mode peer` with `--connect` is a peer still.

`--namespace` is the bus namespace, as in every other command; the robot's ROS 2 namespace is
`--ros-namespace`.
"""

from __future__ import annotations

import json

import click
from click.core import ParameterSource

from ..bus import BusOptions
from ..errors import ConfigError
from ..ros2.bridge import SONAR_MAX_BYTES, RobotLink, run_bridge
from ..ros2.graph import read_graph
from ..ros2.types import DEFAULT_DISTRO, DISTROS, SONAR_TYPES
from .common import bus_options, finite_float, plural

DOMAIN = click.IntRange(0, 232)


def domain_option(f):
    return click.option("--domain", type=DOMAIN, default=0, show_default=True,
                        envvar="ROS_DOMAIN_ID", show_envvar=True,
                        help="The ROS 2 domain (ROS_DOMAIN_ID).")(f)


def ros2_bus(opts: BusOptions) -> BusOptions:
    """Client mode when --connect is given and --mode is not (the module's docstring says why)."""
    ctx = click.get_current_context()
    if opts.connect and ctx.get_parameter_source("mode") in (ParameterSource.DEFAULT, None):
        opts.mode = "client"
    return opts


@click.group()
def ros2() -> None:
    """ROS 2 robots over rmw_zenoh, with no ROS 2 installation (docs/ros2.md)."""


@ros2.command()
@click.option("--robot", "robots", multiple=True, required=True, metavar="ID",
              help="Our robot id (robotN/…); repeat it to bridge a fleet from one process.")
@click.option("--ros-namespace", "ros_namespace", default=None, metavar="NS",
              help="The robot's ROS 2 namespace (default /<robot id>; one robot only).")
@domain_option
@click.option("--cmd-vel", default="cmd_vel", show_default=True, help="The driver's command topic.")
@click.option("--odom", default="odom", show_default=True, help="The driver's odometry topic.")
@click.option("--sonar", default="sonar", show_default=True, help="The driver's sonar topic.")
@click.option("--sonar-type", type=click.Choice(sorted(SONAR_TYPES)), default="pointcloud",
              show_default=True,
              help="sensor_msgs PointCloud (as RosAria published it), PointCloud2 or LaserScan.")
@click.option("--mirror", is_flag=True,
              help="Also publish the robots' architecture traffic (ALLIANCE's "
                   "InterRobotCommunication and Motivation) as ROS 2 topics.")
@click.option("--distro", type=click.Choice(sorted(DISTROS)), default=DEFAULT_DISTRO,
              show_default=True, help="The robot's ROS 2 distro (message definitions, hashes).")
@click.option("--max-sonar-bytes", type=click.IntRange(1, 64 * 1024 * 1024),
              default=SONAR_MAX_BYTES, show_default=True, metavar="BYTES",
              help="A larger sonar sample is dropped before it is decoded (counted).")
@bus_options
def bridge(robots: tuple[str, ...], ros_namespace: str | None, domain: int, cmd_vel: str, odom: str,
           sonar: str, sonar_type: str, mirror: bool, distro: str, max_sonar_bytes: int,
           bus_options: BusOptions) -> None:
    """Map our robotN/cmd_vel, odom and sonar to a ROS 2 robot's topics over rmw_zenoh."""
    if ros_namespace is not None and len(robots) > 1:
        raise ConfigError("--ros-namespace names one robot's namespace: give one --robot with it")
    links = [RobotLink.make(r, ros_namespace, cmd_vel=cmd_vel, odom=odom, sonar=sonar,
                            sonar_type=sonar_type) for r in robots]
    run_bridge(links=links, bus_options=ros2_bus(bus_options), domain=domain, distro=distro,
               mirror=mirror,
               max_sonar_bytes=max_sonar_bytes)


@ros2.command()
@domain_option
@click.option("--wait", type=finite_float(min=0), default=1.0, show_default=True,
              metavar="SECONDS", help="How long to gather liveliness tokens.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object: nodes and topics.")
@bus_options
def graph(domain: int, wait: float, as_json: bool, bus_options: BusOptions) -> None:
    """List ROS 2 nodes and topics from rmw_zenoh's liveliness tokens."""
    snap = read_graph(bus_options=ros2_bus(bus_options), domain=domain, wait=wait)
    if as_json:
        click.echo(json.dumps(snap))
        return
    click.echo(f"ROS 2 domain {domain}: {plural(len(snap['nodes']), 'node')}, "
               f"{plural(len(snap['topics']), 'topic')}, "
               f"{plural(len(snap['services']), 'service')}")
    for node in snap["nodes"]:
        click.echo(f"  {node}")
    for t in snap["topics"]:
        click.echo(f"  {t['topic']} [{', '.join(t['types'])}] "
                   f"{plural(t['publishers'], 'publisher')}, "
                   f"{plural(t['subscriptions'], 'subscription')}")
    for sv in snap["services"]:
        click.echo(f"  {sv['service']} [{', '.join(sv['types'])}] "
                   f"{plural(sv['servers'], 'server')}, {plural(sv['clients'], 'client')}")
