"""central under a real TCP cut (issue 51): the default delivery instance's simulator, five
central robots and the dispatcher in lockstep. robot4 is on a router of its own, linked to the
run's router through the TCP fault proxy (tests/harness/fault_proxy.py; `tc netem` is not
available here); the simulator is a peer of both routers, so robot4 goes on hearing its sensors
and the clock while it is cut off — as a real robot goes on moving — and could go on serving.

The proxy cuts the link while robot4 is serving t3 and restores it 25 s later. Both sides see
a crash: the dispatcher robot4's token go (it re-grants t3 at once), robot4 the dispatcher's
token go — and its teammates'. Before, robot4 took that for its dispatcher's crash and finished
its queue (t3, t4, t2) while the others served the same tasks: three tasks served twice. Each
task must be delivered exactly once, seen from both sides of the cut (an observer on each
router: robot4's events during the cut reach only its own)."""

from __future__ import annotations

import collections
import json
import threading
import time

import pytest

from mrta_delivery.messages import TaskEvent
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.messages import Clock
from mrta_zenoh.toolchain.launchfile import LaunchEvaluator
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.toolchain.runner import command_for, env_for
from tests.harness.fault_proxy import FaultProxy
from tests.harness.helpers import Child, free_port

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

CUT, CUT_AT, HEAL_AT = "robot4", 11.0, 36.0  # robot4 serves t3 from 7.6 s to 12.6 s


def router(children, cfg, name: str, *connect: str) -> str:
    port = free_port()
    r = children.mrta("router", "--listen", f"tcp/127.0.0.1:{port}", "--zenoh-config", cfg,
                      *sum((["--connect", c] for c in connect), []), name=name)
    r.wait_stderr(lambda line: "router listening" in line, 30)
    return f"tcp/127.0.0.1:{port}"


@pytest.mark.timeout(420)
def test_central_serves_every_task_once_across_a_real_tcp_cut(children, tmp_path):
    cfg = tmp_path / "no_gossip.json5"  # nobody finds a way around the cut
    cfg.write_text(json.dumps({"scouting": {"gossip": {"enabled": False}}}))
    main = router(children, cfg, "router")
    proxy = FaultProxy(int(main.rsplit(":", 1)[1]))
    island = router(children, cfg, "router4", proxy.endpoint)
    links = {CUT: ["--mode", "client", "--connect", island],
             "sim": ["--mode", "peer", "--connect", main, "--connect", island,
                     "--zenoh-config", str(cfg)]}
    events: list[tuple[float, str, str, str]] = []
    now = [0.0]
    lock = threading.Lock()

    def on_event(sample) -> None:
        event = (sample.key.split("/")[0], sample.message.event, sample.message.task_id)
        with lock:
            if event not in {e[1:] for e in events}:
                events.append((now[0], *event))

    try:
        with open_bus(BusOptions(mode="client", connect=[main])) as bus, \
                open_bus(BusOptions(mode="client", connect=[island])) as bus4:
            bus.subscribe("clock", lambda s: now.__setitem__(0, s.message.stamp), msg_type=Clock)
            for b in (bus, bus4):
                b.subscribe("*/delivery/*", on_event, msg_type=TaskEvent)
            reg = Registry()
            launch = reg.find("delivery_central").path / "launch" / "delivery_sim.launch"
            nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(launch, {
                "speed": "1", "sim_args": "--duration 60 --lockstep"})
            started = {}
            for n in nodes:
                who = n.name.split("/")[0]
                link = links.get(who, ["--mode", "client", "--connect", main])
                started[who] = Child([*command_for(n), *link], {**children.env, **env_for(n)},
                                     who)
                children.all.append(started[who])
            deadline = time.monotonic() + 240
            for t, act in ((CUT_AT, proxy.cut), (HEAL_AT, proxy.heal)):
                while now[0] < t:
                    assert time.monotonic() < deadline, f"the run did not reach {t} s"
                    time.sleep(0.02)
                act()
            sim = started["sim"]
            assert sim.wait(300) == 0, sim.stderr[-15:]
            for name, child in started.items():
                if name != "sim":
                    child.stop()
            with lock:
                seen = list(events)
    finally:
        proxy.close()
    # the cut struck while robot4 was on t3, and robot4 took it for what it was
    assert (CUT, "started", "t3") in {e[1:] for e in seen if e[0] < CUT_AT}, seen
    assert any("cut off" in line and "holding" in line for line in started[CUT].stderr), \
        started[CUT].stderr[-20:]
    done = collections.Counter(task for _t, _robot, event, task in seen if event == "done")
    assert done == {"t1": 1, "t2": 1, "t3": 1, "t4": 1}, seen
