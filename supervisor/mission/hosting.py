"""A run's robots in agent hosts (robot_agent runtime.agent_host): the launch's agent nodes,
K robots per `mrta host` process, and how the runner tells a hosted robot's injected crash.

The launch file stays what it is for one process per robot — what `mrta launch` runs on real
robots — and the runner regroups its agent nodes: the robots in the application's order, K per
host, each host given a spec (written beside the run's other files) holding each robot's own
verb arguments. The architecture's other processes (central's dispatcher) and the simulator
keep their processes."""

from __future__ import annotations

from pathlib import Path

import yaml

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.installed import entry_points
from mrta_zenoh.processes import Child
from mrta_zenoh.toolchain.launchfile import NodeSpec, executables

HOST_EXECUTABLE = "robot_agent/host"
# the line a robot's agent logs as its crash strikes (mrta_zenoh.failure.crash_now; in a host,
# runtime.agent_host): `robot2: crashing at t=10.00 as asked (fault injection)`
CRASH_MARK = ": crashing at t="


def _verbs() -> dict[str, str]:
    """An executable's entry point → the `mrta` verb registered for the same command."""
    return {ep.value: ep.name for ep in entry_points(group="mrta.commands")}


def host_nodes(nodes: list[NodeSpec], robots: list[str], per_host: int,
               folder: Path) -> tuple[list[NodeSpec], dict[str, str]]:
    """`nodes` with the robots' agent nodes replaced by hosts of `per_host` robots each, and
    each hosted robot's host node name. A robot's agent node is the one named `<robot>/…`
    whose executable is an `mrta` verb; the hosts take the place of the first agent node."""
    if per_host < 1:
        raise ConfigError(f"--agents-per-process {per_host}: at least 1")
    verbs, exes = _verbs(), executables()
    agents: dict[str, NodeSpec] = {}
    for n in nodes:
        robot = n.name.split("/", 1)[0]
        if robot in robots and "/" in n.name and robot not in agents:
            agents[robot] = n
    hosted = [r for r in robots if r in agents]
    folder.mkdir(parents=True, exist_ok=True)
    hosts, where = [], {}
    for i in range(0, len(hosted), per_host):
        group = hosted[i:i + per_host]
        name = f"host{i // per_host + 1}"
        argv, env = [], {}
        for robot in group:
            n = agents[robot]
            if n.params or n.rosparam_files or n.remaps:
                raise ConfigError(f"node {n.name!r}: a hosted robot takes its options as "
                                  "arguments (no <param>, <rosparam> or <remap>)", file=n.file,
                                  line=n.line)
            ep = exes.get(n.executable)
            verb = verbs.get(ep.value) if ep is not None else None
            if verb is None:
                raise ConfigError(f"node {n.name!r}: {n.executable} is no `mrta` agent verb a "
                                  "host can run", file=n.file, line=n.line)
            if env and n.env != env:
                raise ConfigError(f"node {n.name!r}: the robots of one host share its "
                                  "environment, and this one's differs", file=n.file, line=n.line)
            env = dict(n.env)
            argv.append([verb, *n.args])
            where[robot] = name
        spec = folder / f"{name}.yaml"
        spec.write_text(yaml.safe_dump({"name": name, "agents": argv}, sort_keys=False))
        pkg, type_ = HOST_EXECUTABLE.split("/")
        hosts.append(NodeSpec(name, pkg, type_, [str(spec)], env=env))
    out, placed = [], False
    replaced = {id(agents[r]) for r in where}  # by identity: two equal nodes are two nodes
    for n in nodes:
        if id(n) in replaced:
            if not placed:
                out.extend(hosts)
                placed = True
            continue
        out.append(n)
    return out, where


def hosted_crash(child: Child | None, robot: str) -> bool:
    """Whether `robot`, hosted in `child`, crashed as its fault asked (its host says so)."""
    if child is None:
        return False
    mark = robot + CRASH_MARK
    return any(mark in line for line in list(child.stdout))
