"""A mission on a secured fleet (`mrta demo --secure FOLDER`, issue 51): the folder
`mrta secure init` wrote — a CA, a certificate and a Zenoh config per process, the router's —
and every process of the run joining through the fleet's router with its own certificate.

The run starts the router (`router.json5`, where it listens is the fleet's `--endpoint`), and
each process gets its own config: the simulator `simulator.json5`, each robot's agent
`robotN.json5`, the architecture's processes theirs (central: `dispatcher.json5`), the recorder
`recorder.json5`, this process — the supervisor — `supervisor.json5`, a task intake
`tasks.json5`. What the fleet lacks is said up front, as the `mrta secure init` options that
would write it, before any process starts. Agent hosts speak for several robots under one
session, which no robot certificate may: not on a secured fleet.
"""

from __future__ import annotations

import json
import socket
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.errors import ConfigError, MrtaRuntimeError
from mrta_zenoh.processes import ProcessGroup, mrta_argv

SIMULATOR, SUPERVISOR, RECORDER, INTAKE = "simulator", "supervisor", "recorder", "tasks"
READY = 60.0  # wall s for the fleet's router to accept connections


@dataclass(frozen=True)
class Fleet:
    folder: Path

    def config(self, name: str) -> Path:
        return self.folder / f"{name}.json5"

    def args(self, name: str) -> list[str]:
        """A child's bus options: its own certificate's config (a client of the router)."""
        return ["--zenoh-config", str(self.config(name))]

    def bus(self, name: str) -> BusOptions:
        return BusOptions(zenoh_config=self.config(name))

    @property
    def endpoint(self) -> str:
        """Where the fleet's router listens (router.json5, written by `mrta secure init`)."""
        listen = json.loads(self.config("router").read_text())["listen"]["endpoints"]
        return listen[0]

    def start_router(self, hub: ProcessGroup) -> None:
        """The fleet's router, in `hub`, up once its endpoint accepts connections."""
        start_router(hub, ["--zenoh-config", str(self.config("router"))], self.endpoint,
                     "the fleet's router")


def start_router(hub: ProcessGroup, args: list[str], endpoint: str, what: str) -> None:
    """`mrta router ARGS` in `hub`, up once `endpoint` accepts connections (a run's own router,
    a fleet's); MrtaRuntimeError with its output if it ends or is not up within READY."""
    router = hub.start(mrta_argv("router", *args), name="router", merge_stderr=True)
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    deadline = time.monotonic() + READY
    while True:
        try:
            socket.create_connection((host.strip("[]"), int(port)), timeout=1).close()
            return
        except OSError:
            if not router.running() or time.monotonic() > deadline:
                raise MrtaRuntimeError(f"{what} ({endpoint}) did not come up:\n"
                                       f"{router.tail()}") from None
            time.sleep(0.05)


def fleet(folder: Path, robots: Iterable[str], processes: Iterable[str],
          intake: bool) -> Fleet:
    """The fleet in `folder`, checked to hold a config for every process of the run (module
    docstring); ConfigError naming what `mrta secure init` is missing otherwise."""
    f = Fleet(folder)
    if not f.config("router").is_file():
        raise ConfigError(f"--secure {folder}: no router.json5 there — make the fleet with "
                          f"`mrta secure init {folder} --robot … --observer supervisor "
                          "--observer recorder`")
    wanted = [(SIMULATOR, "(its default; not --no-simulator)"),
              (SUPERVISOR, "--observer supervisor"), (RECORDER, "--observer recorder")]
    wanted += [(r, f"--robot {r}") for r in robots]
    wanted += [(p, f"--process {p}") for p in processes]
    if intake:
        wanted.append((INTAKE, "--submitter NAME (it adds the run's intake, tasks)"))
    missing = [how for name, how in wanted if not f.config(name).is_file()]
    if missing:
        raise ConfigError(f"--secure {folder}: the fleet has no certificate for every process "
                          f"of this run; `mrta secure init` it with {', '.join(missing)}")
    return f
