"""central on a secured fleet (issue 51.4): `mrta secure init --process dispatcher`, a router with
mutual TLS and default-deny access control, the default delivery instance's simulator, five
central robots and the dispatcher, each with its own certificate. A certified robot (robot1's
certificate, tests/procs/secured_forger.py) forges once: a queue to robot2 under the
dispatcher's key (the router drops it), the same under its own key (robot2 refuses it), a
report claiming others' tasks served (the dispatcher refuses those) and a `done` for a task it
never started (every board refuses it). Every task is still delivered, once, by a real robot,
and each refusal is counted in its receiver's tally (what every run's summary lists)."""

from __future__ import annotations

import collections
import os
import threading

import pytest
from click.testing import CliRunner

from mrta_agent.central.messages import Queue
from mrta_delivery.messages import TaskEvent
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.cli.main import cli
from mrta_zenoh.refusal_tally import EVERY_REFUSED, RefusedTally
from mrta_zenoh.toolchain.launchfile import LaunchEvaluator
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.toolchain.runner import command_for, env_for
from tests.harness.helpers import Child, free_port
from tests.test_secure import wait_accepting

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

ROBOTS = ("robot1", "robot2", "robot3", "robot4", "robot5")
MARK = 7_777_777  # the forger's seq (tests/procs/secured_forger.py)


@pytest.mark.timeout(420)
def test_central_runs_on_a_secured_fleet_and_a_certified_robots_forgeries_are_refused(
        children, tmp_path):
    folder, endpoint = tmp_path / "fleet", f"tls/127.0.0.1:{free_port()}"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), *sum(
        (["--robot", r] for r in ROBOTS), []), "--process", "dispatcher",
        "--observer", "watcher", "--endpoint", endpoint])
    assert result.exit_code == 0, result.output
    router = children.mrta("router", "--zenoh-config", folder / "router.json5", name="router")
    router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
    wait_accepting(endpoint)

    tallies: dict[str, dict] = {}
    done: list[tuple[str, str, int]] = []
    queues: list[tuple[str, int]] = []
    lock = threading.Lock()

    def keep(what, item):
        with lock:
            what(item)

    with open_bus(BusOptions(zenoh_config=folder / "watcher.json5")) as bus:
        bus.subscribe(EVERY_REFUSED, lambda s: keep(lambda m: tallies.__setitem__(
            m.header.frame_id, m.entries()), s.message), msg_type=RefusedTally)
        bus.subscribe("*/delivery/done", lambda s: keep(done.append, (
            s.key.split("/")[0], s.message.task_id, s.message.header.seq)), msg_type=TaskEvent)
        bus.subscribe("dispatcher/central/queue/robot2", lambda s: keep(queues.append, (
            s.message.header.frame_id, s.message.header.seq)), msg_type=Queue)
        reg = Registry()
        launch = reg.find("delivery_central").path / "launch" / "delivery_sim.launch"
        nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(launch, {
            "speed": "0", "sim_args": "--duration 40 --lockstep"})
        identity = {"sim": "simulator", "dispatcher": "dispatcher"}
        started = {}
        for n in nodes:  # as the launch runner starts them, each with its own certificate
            who = identity.get(n.name, n.name.split("/")[0])
            started[who] = Child([*command_for(n), "--zenoh-config", str(folder / f"{who}.json5")],
                                 {**children.env, **env_for(n)}, who)
            children.all.append(started[who])
        forger = children.python("secured_forger.py", folder / "robot1.json5", "t2,t3,t4", "t3",
                                 name="forger")
        forger.wait_json(lambda o: "forged" in o, 180)
        sim = started["simulator"]
        assert sim.wait(300) == 0, sim.stderr[-15:]
        assert any("lockstep with 6 participants" in line for line in sim.stderr), \
            sim.stderr[-15:]
        for name, child in started.items():
            if name != "simulator":
                child.stop()
        with lock:
            tallies, done, queues = dict(tallies), list(done), list(queues)

    real = collections.Counter(task for robot, task, seq in done if seq != MARK)
    assert real == {"t1": 1, "t2": 1, "t3": 1, "t4": 1}, done  # each delivered once, for real
    assert (("robot1", "t3", MARK)) in done  # the forged done was said (and refused below)
    assert all(seq != MARK for _, seq in queues), queues  # the router dropped the forged queue
    assert any(k == ("queue", "robot1", "misaddressed", True) for k in tallies["robot2"]), tallies
    assert tallies["dispatcher"].get(("progress", "robot1", "not_granted", True)) == 3, tallies
    assert any(s == "robot1" and r == "done_not_started" for robot, t in tallies.items()
               if robot != "robot1" for (_k, s, r, _f) in t), tallies
