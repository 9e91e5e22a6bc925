"""A process's own samples reach its own subscriptions in-process (ZenohBus): before
publish() returns, once each — never a second time from Zenoh — decoded and counted as samples
from the network are; other sessions still get them over the network. Real sessions on
loopback, in the test process."""

import threading
import time

import pytest

from mrta_zenoh import codec
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.zenoh_bus import ZenohBus
from mrta_zenoh.messages import Odometry, Twist
from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess


@pytest.fixture
def pair():
    port = free_port()
    here = ZenohBus(BusOptions(listen=[f"tcp/127.0.0.1:{port}"]))
    there = ZenohBus(BusOptions(connect=[f"tcp/127.0.0.1:{port}"], listen=["tcp/127.0.0.1:0"]))
    try:
        yield here, there
    finally:
        there.close()
        here.close()


def test_own_samples_are_handed_over_before_publish_returns_and_only_once(pair):
    here, there = pair
    counts = here.enable_counting()
    mine, wide, remote = [], [], threading.Event()
    got_remote = []
    here.subscribe("robot1/cmd_vel", lambda s: mine.append((s.message, threading.get_ident())),
                   msg_type=Twist)
    here.subscribe("robot1/**", lambda s: wide.append(s.key))
    queue = here.subscribe("robot1/*", None)  # no handler: pulled with get()
    there.subscribe("robot1/cmd_vel", lambda s: (got_remote.append(s.message), remote.set()),
                    msg_type=Twist)
    deadline = time.monotonic() + 10
    while not remote.is_set():  # until `there`'s subscription has reached `here`
        here.publish("robot1/cmd_vel", Twist(0.0, 0.0))
        assert time.monotonic() < deadline, "the remote subscription never matched"
        remote.wait(0.1)
    mine.clear(), wide.clear()
    while queue.get(0) is not None:  # the warm-up's
        pass
    before = len(got_remote)
    counted = {s.key_expr: s.counts["robot1/cmd_vel"] for s in counts.tallies()}

    here.publish("robot1/cmd_vel", Twist(0.5, 0.1))
    assert mine == [(Twist(0.5, 0.1), threading.get_ident())]  # already, on this thread
    assert wide == ["robot1/cmd_vel"]
    here.publish_raw("robot1/cmd_vel", codec.encoding_for(Twist.TYPE_NAME),
                     codec.encode(Twist(0.2, 0.0)))
    batch = here.declare_batch(["robot1/cmd_vel", "robot2/cmd_vel"],
                               [codec.encoding_for(Twist.TYPE_NAME)] * 2)
    batch.publish([codec.encode(Twist(0.3, 0.0)), codec.encode(Twist(9.0, 0.0))])
    batch.publish([codec.encode(Twist(9.0, 0.0)), codec.encode(Twist(0.4, 0.0))], rows=[1])
    sent = [Twist(0.5, 0.1), Twist(0.2, 0.0), Twist(0.3, 0.0)]
    assert [m for m, _ in mine] == sent
    assert wide == ["robot1/cmd_vel"] * 3  # robot2's is none of its keys
    # taken into account (lockstep's books) by the time publish returned, by each of them
    assert {s.key_expr: s.counts["robot1/cmd_vel"] - counted[s.key_expr]
            for s in counts.tallies()} == \
        {"robot1/cmd_vel": 3, "robot1/**": 3, "robot1/*": 3}
    time.sleep(0.5)  # Zenoh would have handed them over again by now
    assert len(mine) == 3 and len(wide) == 3
    assert [queue.get(0).message for _ in range(3)] == sent and queue.get(0) is None
    deadline = time.monotonic() + 10
    while len(got_remote) < before + 3 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert got_remote[before:] == sent


def test_a_subscription_that_comes_or_goes_is_seen_at_the_next_publish(pair):
    here, _ = pair
    got = []
    here.publish("robot1/cmd_vel", Twist(0.0, 0.0))  # remembered: nobody here hears it
    sub = here.subscribe("robot1/cmd_vel", lambda s: got.append(s.message), msg_type=Twist)
    here.publish("robot1/cmd_vel", Twist(1.0, 0.0))
    sub.close()
    here.publish("robot1/cmd_vel", Twist(2.0, 0.0))
    assert got == [Twist(1.0, 0.0)]


def test_a_malformed_own_sample_is_counted_and_dropped_like_a_remote_one(pair):
    here, _ = pair
    got = []
    sub = here.subscribe("robot1/cmd_vel", lambda s: got.append(s), msg_type=Twist)
    here.publish_raw("robot1/cmd_vel", codec.encoding_for(Twist.TYPE_NAME), b"\xc1not msgpack")
    assert got == [] and sub.malformed == 1


def test_what_a_subscriptions_hook_raises_reaches_neither_the_publisher_nor_the_others(pair):
    here, _ = pair

    def refuse(key, exc):
        raise RuntimeError("a hook that fails")

    first = here.subscribe("robot1/cmd_vel", lambda s: None, msg_type=Twist, on_error=refuse)
    second = here.subscribe("robot1/cmd_vel", lambda s: None, msg_type=Twist)
    errors = here.stats["handler_errors"]
    here.publish_raw("robot1/cmd_vel", codec.encoding_for(Twist.TYPE_NAME), b"\xc1not msgpack")
    assert first.malformed == 1 and second.malformed == 1
    assert here.stats["handler_errors"] == errors + 1


def test_an_own_sample_is_decoded_once_for_all_the_subscriptions_it_reaches(pair):
    """An agent host's robots share one decode of a teammate's message (issue 47), each still
    filtering by type and counting it; a generic message (a mutable dict inside) is not
    shared."""
    here, _ = pair
    counts = here.enable_counting()
    typed, untyped, generic = [], [], []
    for _ in range(3):
        here.subscribe("*/cmd_vel", typed.append, msg_type=Twist)
    here.subscribe("robot1/*", untyped.append)
    other = here.subscribe("robot1/cmd_vel", lambda s: None, msg_type=Odometry)
    here.publish("robot1/cmd_vel", Twist(0.5, 0.1))
    assert len(typed) == 3 and len(untyped) == 1
    assert all(s.message is typed[0].message for s in typed + untyped)  # one decode
    assert other.wrong_type == 1 and other.received == 0
    assert sorted(t.counts["robot1/cmd_vel"] for t in counts.tallies()) == [0, 1, 1, 1, 1]
    for _ in range(2):
        here.subscribe("robot1/note", generic.append)
    here.publish_raw("robot1/note", codec.encoding_for("no_msgs/Note"),
                     codec.encode_struct({"text": "hi"}))
    assert [s.message.data for s in generic] == [{"text": "hi"}] * 2
    assert generic[0].message is not generic[1].message
    here.publish_raw("robot1/cmd_vel", codec.encoding_for(Twist.TYPE_NAME), b"\xc1not msgpack")
    assert len(typed) == 3
    assert [s.malformed for s in here._subs[:4]] == [1, 1, 1, 1]  # each counts it


def test_a_remote_sample_is_decoded_once_for_all_the_subscriptions_on_its_key_expression(pair):
    """One native subscriber per key expression, fanned out (issue 47): an agent host's robots
    share one decode of a teammate's sample from another process, each still filtering by type
    and counting it and its malformed samples; one that leaves stops hearing, the rest go on,
    and the last one's leaving undeclares the native subscriber."""
    here, there = pair
    counts = here.enable_counting()
    typed, queued = [], here.subscribe("*/cmd_vel", None, msg_type=Twist)
    subs = [here.subscribe("*/cmd_vel", typed.append, msg_type=Twist) for _ in range(3)]
    other = here.subscribe("*/cmd_vel", lambda s: None, msg_type=Odometry)
    assert list(here._fans) == ["*/cmd_vel"]  # one native subscriber for the five
    deadline = time.monotonic() + 10
    while not typed:  # until `here`'s subscriber has reached `there`
        there.publish("robot1/cmd_vel", Twist(0.0, 0.0))
        assert time.monotonic() < deadline, "the remote subscription never matched"
        time.sleep(0.1)
    time.sleep(0.3)
    typed.clear()
    while queued.get(0) is not None:
        pass
    base = {id(t): t.counts["robot1/cmd_vel"] for t in counts.tallies()}
    wrong = other.wrong_type

    def settle(n: int) -> None:
        deadline = time.monotonic() + 10
        while len(typed) < n and time.monotonic() < deadline:
            time.sleep(0.02)

    there.publish("robot1/cmd_vel", Twist(0.5, 0.1))
    settle(3)
    assert [s.message for s in typed] == [Twist(0.5, 0.1)] * 3
    assert all(s.message is typed[0].message for s in typed)  # one decode
    assert queued.get(1).message is typed[0].message
    assert other.wrong_type == wrong + 1 and other.received == 0
    assert sorted(t.counts["robot1/cmd_vel"] - base[id(t)] for t in counts.tallies()) == \
        [0, 1, 1, 1, 1]
    there.publish_raw("robot1/cmd_vel", codec.encoding_for(Twist.TYPE_NAME), b"\xc1not msgpack")
    deadline = time.monotonic() + 10
    while subs[2].malformed < 1 and time.monotonic() < deadline:
        time.sleep(0.02)
    assert [s.malformed for s in [queued, *subs]] == [1, 1, 1, 1]  # each counts it
    for s in (queued, other, subs[0], subs[1]):
        s.close()
    typed.clear()
    there.publish("robot1/cmd_vel", Twist(0.7, 0.0))
    settle(1)
    time.sleep(0.2)
    assert [s.message for s in typed] == [Twist(0.7, 0.0)]  # the one left, alone
    subs[2].close()
    assert here._fans == {}
