"""One way to start a process of a run (mrta_zenoh.node.Node): the identity check before
anything opens, the clock each kind of process gets, signals, the bus, lockstep, its own token,
and faulthandler — the same for a robot, an observer and a process that is neither (a
dispatcher), which the tests here start as a registered role of its own."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading

import pytest

from mrta_zenoh import node as node_module
from mrta_zenoh.bus import BusOptions, InProcBus
from mrta_zenoh.bus.inproc import InProcNetwork
from mrta_zenoh.clock import SimClock, WallClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.identity import OBSERVER, ROBOT
from mrta_zenoh.keys import CLOCK, CLOCK_SOURCE_TOKEN
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.lockstep.protocol import PARTICIPANT
from mrta_zenoh.messages import Clock as ClockMsg
from mrta_zenoh.node import Node, NodeTime


def tokens_on(net: InProcNetwork) -> tuple[InProcBus, set[str]]:
    """A second process's view of the liveliness tokens on `net`."""
    seen: set[str] = set()
    watcher = InProcBus(net)
    watcher.watch_liveliness("**", lambda k, alive: (seen.add if alive else seen.discard)(k))
    watcher.watch_liveliness("@mrta/**", lambda k, alive: (seen.add if alive else seen.discard)(k))
    return watcher, seen


def test_the_identity_is_checked_first_and_not_for_a_bus_opened_elsewhere(monkeypatch):
    calls, opened = [], []
    monkeypatch.setattr(node_module, "check_identity",
                        lambda *args: calls.append(args) or (_ for _ in ()).throw(
                            ConfigError("its certificate is for robot2, not for robot robot1")))
    monkeypatch.setattr(node_module, "open_bus", lambda options: opened.append(options))
    options = BusOptions()
    with pytest.raises(ConfigError, match="robot2"):
        Node(options, ROBOT, name="robot1")
    assert calls == [(options, ROBOT, "robot1", ())] and opened == []  # refused before the bus
    calls.clear()
    with Node(options, ROBOT, name="robot1", bus=InProcBus()):
        pass
    assert calls == [] and opened == []


def test_each_kind_of_time_gets_its_clock_and_sim_time_follows_the_simulator():
    net = InProcNetwork()
    with Node(BusOptions(), OBSERVER, bus=InProcBus(net)) as wall:
        assert isinstance(wall.clock, WallClock) and wall.wait_for_clock()
    with Node(BusOptions(), OBSERVER, time=NodeTime.SIM, bus=InProcBus(net)) as observer:
        assert type(observer.clock) is SimClock and not observer.clock.started.is_set()
        sim = InProcBus(net)
        source = sim.declare_token(f"{CLOCK_SOURCE_TOKEN}/run-x1")
        sim.publish(CLOCK, ClockMsg(1.5, "run-x1"))
        assert observer.wait_for_clock() and observer.clock.now() == 1.5
        source.close()
    sim.publish(CLOCK, ClockMsg(2.5, "run-x1"))
    assert observer.clock.now() == 1.5  # closed with the node: it follows no more


def test_a_lockstep_participant_joins_before_it_declares_itself_alive_and_leaves_on_exit():
    net = InProcNetwork()
    _, seen = tokens_on(net)
    order = []
    with Node(BusOptions(), "dispatcher", name="dispatcher", time=NodeTime.LOCKSTEP,
              bus=InProcBus(net)) as node:
        assert isinstance(node.clock, LockstepClock) and node.clock.participant == "dispatcher"
        order.append(set(seen))
        node.declare_alive("@mrta/dispatcher/d1")
        order.append(set(seen))
    assert order == [{f"{PARTICIPANT}/dispatcher"},
                     {f"{PARTICIPANT}/dispatcher", "@mrta/dispatcher/d1"}]
    assert seen == set()  # everything the node held went with it
    with pytest.raises(ValueError, match="needs a name"):
        Node(BusOptions(), "dispatcher", time=NodeTime.LOCKSTEP)


def test_a_signal_sets_the_nodes_stop_and_the_handlers_are_restored():
    before = signal.getsignal(signal.SIGTERM)
    with Node(BusOptions(), OBSERVER, bus=InProcBus()) as node:
        assert not node.stop.is_set()
        signal.raise_signal(signal.SIGTERM)
        assert node.stop.is_set()
    assert signal.getsignal(signal.SIGTERM) is before
    stop = threading.Event()
    with Node(BusOptions(), OBSERVER, bus=InProcBus(), stop=stop) as node:
        assert node.stop is stop  # the caller's event, also set by signals


def test_a_bus_given_is_left_open_and_held_resources_close_with_the_node():
    bus = InProcBus()
    got = []
    with Node(BusOptions(), OBSERVER, bus=bus) as node:
        node.hold(bus.subscribe("a", got.append))
        bus.publish("a", ClockMsg(1.0, "r"))
    bus.publish("a", ClockMsg(2.0, "r"))
    assert [s.message.stamp for s in got] == [1.0] and not bus.closed


PROBE = """
import faulthandler, sys
from mrta_zenoh.bus import BusOptions, InProcBus
from mrta_zenoh.node import Node
assert not faulthandler.is_enabled()
with Node(BusOptions(), "observer", bus=InProcBus()):
    print("enabled" if faulthandler.is_enabled() else "off", flush=True)
    faulthandler._sigsegv()
"""


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_segfault_prints_the_stack_of_every_thread_to_stderr():
    """Every process enables faulthandler, so a crash in a C extension leaves its
    Python stack in the run's log instead of a bare `killed by SIGSEGV`."""
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == -signal.SIGSEGV
    assert out.stdout.strip() == "enabled"
    assert "Fatal Python error: Segmentation fault" in out.stderr
    assert 'File "<string>", line 8 in <module>' in out.stderr, out.stderr
