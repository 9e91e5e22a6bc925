"""Run launch-file nodes as child processes: prefixed output, stop all on Ctrl-C or on a failure.

The process handling is mrta_zenoh.processes (the same manager the demo and the tests use).
"""

from __future__ import annotations

import json
import sys
import threading
from typing import Callable

from ..processes import Child, ProcessGroup
from .launchfile import NodeSpec


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


def run_nodes(nodes: list[NodeSpec], stop: threading.Event,
              echo: Callable[[str], None] = print, grace: float = 5.0) -> int:
    """Start every node; return 0 when all exit cleanly, 1 when one fails (the rest are stopped)."""
    lock = threading.Lock()

    def prefixed(name: str, line: str) -> None:
        with lock:
            echo(f"[{name}] {line}")

    with ProcessGroup(echo=prefixed) as group:
        children = start_nodes(group, nodes)
        while not stop.is_set():
            if group.failed() or all(not c.running() for c in children):
                break
            stop.wait(0.1)
        failed = [] if stop.is_set() else group.failed()
        group.stop_all(grace)
    for c in children:
        prefixed(c.name, f"exited with code {c.returncode}")
    return 1 if failed else 0
