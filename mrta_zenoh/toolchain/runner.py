"""Run launch-file nodes as child processes: prefixed output, stop all on Ctrl-C or on a failure.

Children are started with subprocess (a fresh interpreter each, never a fork of a process that
has Zenoh loaded) and are the only processes this ever signals.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from typing import Callable

from .launchfile import NodeSpec


def command_for(node: NodeSpec) -> list[str]:
    return [sys.executable, "-m", "mrta_zenoh.toolchain.run_node", node.executable, *node.args]


def env_for(node: NodeSpec) -> dict[str, str]:
    env = dict(os.environ)
    env.update(node.env)
    if node.params or node.rosparam_files:
        env["MRTA_NODE_PARAMS"] = json.dumps({"name": node.name, "params": node.params,
                                              "rosparam_files": node.rosparam_files})
    env["PYTHONUNBUFFERED"] = "1"
    return env


def run_nodes(nodes: list[NodeSpec], stop: threading.Event,
              echo: Callable[[str], None] = print, grace: float = 5.0) -> int:
    """Start every node; return 0 when all exit cleanly, 1 when one fails (the rest are stopped)."""
    procs: list[tuple[NodeSpec, subprocess.Popen]] = []
    lock = threading.Lock()
    failed = threading.Event()
    result = {"code": 0}

    def pump(node: NodeSpec, proc: subprocess.Popen) -> None:
        for line in proc.stdout:
            with lock:
                echo(f"[{node.name}] {line.rstrip()}")
        rc = proc.wait()
        with lock:
            echo(f"[{node.name}] exited with code {rc}")
        if rc != 0 and not stop.is_set():
            result["code"] = 1
            failed.set()

    threads = []
    try:
        for node in nodes:
            proc = subprocess.Popen(command_for(node), env=env_for(node), stdout=subprocess.PIPE,
                                    stderr=subprocess.STDOUT, text=True, stdin=subprocess.DEVNULL)
            procs.append((node, proc))
            t = threading.Thread(target=pump, args=(node, proc), daemon=True)
            t.start()
            threads.append(t)
        while not stop.is_set() and not failed.is_set():
            if all(p.poll() is not None for _, p in procs):
                break
            stop.wait(0.1)
    finally:
        for _, p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGINT)
        for _, p in procs:
            try:
                p.wait(grace)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        for t in threads:
            t.join(2.0)
    return result["code"]
