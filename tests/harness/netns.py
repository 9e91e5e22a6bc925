"""Robots in network namespaces: real separate network stacks, linked to the host by veth pairs.

Each robot's island (its Zenoh router, agent and sensors) runs in a namespace of its own with
`eth0` = 10.213.N.2/24; the host end of the pair is 10.213.N.1, where the central router
listens. A partition takes the host end of a robot's link down. Only addresses of namespaces
made here are used; everything is removed on exit (namespaces, and with them the veth pairs).
"""

from __future__ import annotations

import os
import subprocess
import sys

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.lifecycle import Closing
from tests.harness.helpers import Child, Tokens, free_port
from tests.process.test_network_faults import NO_GOSSIP, Fleet

PREFIX = f"mrta{os.getpid() % 100000}"


def sh(*args: str) -> None:
    subprocess.run(args, check=True, capture_output=True, timeout=30)


class NamespaceFleet(Fleet, Closing):
    def __init__(self, children, tmp_path, robots: dict, tasks):
        import json

        self.children, self.tmp = children, tmp_path
        self.cfg = tmp_path / "no_gossip.json5"
        self.cfg.write_text(json.dumps(NO_GOSSIP))
        self.names = list(robots)
        self.ns = {r: f"{PREFIX}n{i}" for i, r in enumerate(self.names, 1)}
        self.veth = {r: f"{PREFIX}v{i}" for i, r in enumerate(self.names, 1)}
        self.addr = {r: (f"10.213.{i}.1", f"10.213.{i}.2") for i, r in enumerate(self.names, 1)}
        self._made: list[str] = []
        self.tokens = None
        try:
            for r in self.names:
                ns, veth, (host, inner) = self.ns[r], self.veth[r], self.addr[r]
                sh("ip", "netns", "add", ns)
                self._made.append(ns)
                sh("ip", "link", "add", veth, "type", "veth", "peer", "name", "eth0", "netns", ns)
                sh("ip", "addr", "add", f"{host}/24", "dev", veth)
                sh("ip", "link", "set", veth, "up")
                sh("ip", "netns", "exec", ns, "ip", "link", "set", "lo", "up")
                sh("ip", "netns", "exec", ns, "ip", "addr", "add", f"{inner}/24", "dev", "eth0")
                sh("ip", "netns", "exec", ns, "ip", "link", "set", "eth0", "up")
            self.central_port = free_port()
            listen = [f"tcp/127.0.0.1:{self.central_port}"] + \
                [f"tcp/{self.addr[r][0]}:{self.central_port}" for r in self.names]
            self.central = self._start(None, "central", "router", *sum((["--listen", e]
                                                                        for e in listen), []),
                                       "--zenoh-config", str(self.cfg))
            self.central.wait_stderr(lambda line: "router listening" in line, 30)
            self.agents = {}
            for r in self.names:
                port = 17000 + self.names.index(r)  # inside its own namespace: always free
                local = f"tcp/127.0.0.1:{port}"
                router = self._start(r, f"{r} router", "router", "--listen", local, "--connect",
                                     f"tcp/{self.addr[r][0]}:{self.central_port}",
                                     "--zenoh-config", str(self.cfg))
                router.wait_stderr(lambda line: "router listening" in line, 30)
                self.agents[r] = self._start(r, r, "agent", r, "--robot-params", str(robots[r]),
                                             "--tasks-params", str(tasks), "--mode", "client",
                                             "--connect", local)
                self._start(r, f"{r} sensors", None, "--connect", local, r)
            self.echo = self._start(None, "observer", "echo",
                                    "*/alliance/inter_robot_communication", "--json",
                                    "--mode", "client", "--connect",
                                    f"tcp/127.0.0.1:{self.central_port}")
            # every agent's token, seen through the central router: islands up and joined
            self.tokens = Tokens(options=BusOptions(
                mode="client", connect=[f"tcp/127.0.0.1:{self.central_port}"]))
            self.tokens.wait_all([f"{r}/alliance/agent" for r in self.names], 60,
                                 *self.agents.values())
        except BaseException:
            self.close()
            raise

    def _start(self, robot: str | None, name: str, verb: str | None, *args: str) -> Child:
        if verb is None:  # the sensor feeder script
            from tests.harness.helpers import PROCS
            cmd = [sys.executable, str(PROCS / "sensor_feeder.py"), *args]
        else:
            cmd = [sys.executable, "-m", "mrta_zenoh.cli.main", verb, *args]
        if robot is not None:
            cmd = ["ip", "netns", "exec", self.ns[robot], *cmd]
        child = Child(cmd, self.children.env, name)
        self.children.all.append(child)
        return child

    def link(self, robot: str, up: bool) -> None:
        sh("ip", "link", "set", self.veth[robot], "up" if up else "down")

    def close(self) -> None:
        if self.tokens is not None:
            self.tokens.close()
        self.children.stop_all()
        for ns in self._made:
            subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)
        self._made.clear()

