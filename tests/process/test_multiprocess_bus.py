"""Real Zenoh sessions on loopback between separate processes (subprocess, never fork)."""

import signal
import time

import pytest

pytestmark = pytest.mark.multiprocess

NAMES = ["A", "B", "C"]


def sees_all(names):
    return lambda o: set(names) <= set(o.get("seen", ()))


def start(children, names, tokens=None):
    """With `tokens`, one after the other: each peer's token alive (its session open, the first
    holding the rendezvous) before the next starts; without, all at once."""
    procs = {}
    for n in names:
        procs[n] = children.python("peer.py", n, name=n)
        if tokens is not None:
            tokens.wait(f"test/{n}/alive", 15, procs[n])
    return procs


@pytest.mark.parametrize("order,gap", [
    (["A", "B", "C"], True),
    (["C", "A", "B"], True),
    (["B", "C", "A"], False),  # all at once: they race for the rendezvous port
])
def test_three_processes_exchange_typed_messages_in_any_start_order(children, tokens, order,
                                                                    gap):
    procs = start(children, order, tokens if gap else None)
    for n in NAMES:
        procs[n].wait_json(sees_all(NAMES), 20)


@pytest.mark.slow
def test_rest_keep_talking_when_the_rendezvous_exits_and_a_newcomer_takes_over(children, tokens):
    procs = start(children, ["A", "B", "C"], tokens)  # A started first: it holds the rendezvous
    for n in NAMES:
        procs[n].wait_json(sees_all(NAMES), 20)
    procs["A"].signal(signal.SIGTERM)
    assert procs["A"].wait(5) == 0
    # Drain reports from before the exit, then B and C must still hear each other (and not A).
    for n in ("B", "C"):
        procs[n].wait_json(lambda o: o.get("seen") and "A" not in o["seen"]
                           and {"B", "C"} <= set(o["seen"]), 10)
    d = children.python("peer.py", "D", name="D")  # takes the free rendezvous over
    for p in (procs["B"], procs["C"], d):
        p.wait_json(sees_all(["B", "C", "D"]), 20)


def test_sigkilled_process_is_reported_gone_by_liveliness_within_one_second(children, tokens):
    procs = start(children, ["A", "B", "C"], tokens)
    procs["C"].wait_json(lambda o: o.get("event") == "alive" and o["key"] == "test/B/alive", 15,
                             from_start=True)
    t_kill = time.time()
    procs["B"].signal(signal.SIGKILL)
    gone = procs["C"].wait_json(lambda o: o.get("event") == "gone" and o["key"] == "test/B/alive", 5)
    latency = gone["t"] - t_kill
    print(f"liveliness loss seen {latency * 1000:.1f} ms after SIGKILL")
    assert 0 <= latency < 1.0  # gone because of the kill, not before it
