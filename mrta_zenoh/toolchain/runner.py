"""Run launch-file nodes as child processes, with roslaunch's policy for a node that ends.

* Every node's end is reported the moment it is seen, in one line: `[sim] exited with code 1`,
  `[sim] killed by SIGKILL` (a `kill -9` from outside is a death like any other), `[sim] exited
  normally`. Nodes this launch stopped itself (Ctrl-C, shutdown) are `stopped`, not failures.
* A node marked `required="true"` brings the whole launch down when it ends, for whatever
  reason, as in roslaunch; any other node that ends is reported and the rest keep running.
* The launch ends when a required node ends, when every node has ended, or on Ctrl-C; its result
  says which nodes failed (the verb exits 1 if any did, 130 on Ctrl-C).

The process handling is mrta_zenoh.processes (the same manager the demo and the tests use).
"""

from __future__ import annotations

import json
import sys
import threading
from dataclasses import dataclass, field
from typing import Callable

from ..processes import Child, ProcessGroup
from .launchfile import NodeSpec

POLL = 0.1  # seconds between looks at the children: a death is reported within this


def command_for(node: NodeSpec) -> list[str]:
    return [sys.executable, "-m", "mrta_zenoh.cli.run_node", node.executable, *node.args]


def env_for(node: NodeSpec) -> dict[str, str]:
    env = dict(node.env)
    if node.params or node.rosparam_files:
        env["MRTA_NODE_PARAMS"] = json.dumps({"name": node.name, "params": node.params,
                                              "rosparam_files": node.rosparam_files})
    env["PYTHONUNBUFFERED"] = "1"
    return env


def start_nodes(group: ProcessGroup, nodes: list[NodeSpec]) -> list[Child]:
    """Start every node in `group` (output merged, prefixed by the group's echo)."""
    return [group.start(command_for(n), name=n.name, env=env_for(n), merge_stderr=True)
            for n in nodes]


@dataclass
class LaunchResult:
    failed: list[str] = field(default_factory=list)   # "name: how it ended", in order seen
    interrupted: bool = False                          # stopped by the stop event (Ctrl-C)
    brought_down_by: str | None = None                 # the required node whose end stopped all


def run_nodes(nodes: list[NodeSpec], stop: threading.Event,
              echo: Callable[[str], None] = print, grace: float = 5.0,
              notify: Callable[[str], None] | None = None) -> LaunchResult:
    """Start every node and watch them until a required one ends, all have ended, or `stop`.
    `echo` gets the nodes' output lines, prefixed `[name] `; `notify` the lines saying how each
    node ended (default: echo)."""
    lock = threading.Lock()
    notify = notify or echo
    result = LaunchResult()

    def prefixed(name: str, line: str) -> None:
        with lock:
            echo(f"[{name}] {line}")

    def ended(child: Child, required: bool) -> None:
        child.wait(grace)  # its last output lines come before the line saying it ended
        how = child.describe_exit()
        extra = ""
        if required and result.brought_down_by is None and not result.interrupted:
            result.brought_down_by = child.name
            extra = " — a required node: stopping every node"
        with lock:
            notify(f"[{child.name}] {how}{extra}")
        if child.failed():
            result.failed.append(f"{child.name} {how}")

    with ProcessGroup(echo=prefixed) as group:
        children = start_nodes(group, nodes)
        required = {id(c) for c, n in zip(children, nodes) if n.required}
        seen: set[int] = set()
        while True:
            if stop.is_set():
                result.interrupted = True
                group.interrupted()
                break
            for c in children:
                if id(c) not in seen and not c.running():
                    seen.add(id(c))
                    ended(c, id(c) in required)
            if result.brought_down_by is not None or len(seen) == len(children):
                break
            stop.wait(POLL)
        group.stop_all(grace)
        for c in children:
            if id(c) not in seen:
                ended(c, False)
    return result
