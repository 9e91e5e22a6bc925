import logging

import msgpack
import pytest

from mrta_zenoh.bus import InProcBus, InProcNetwork
from mrta_zenoh.codec import encoding_for
from mrta_zenoh.messages import Header, Twist
from mrta_agent.alliance.messages import InterRobotCommunication


def irc(frame, seq=0):
    return InterRobotCommunication(Header(frame, 0.0, seq), "wander", 1.0)


def test_wildcard_subscription_receives_typed_messages():
    bus = InProcBus()
    got = []
    bus.subscribe("*/alliance/inter_robot_communication", got.append)
    bus.publish("robot1/alliance/inter_robot_communication", irc("robot1"))
    bus.publish("robot2/cmd_vel", Twist(1.0, 0.0))
    assert [(s.key, s.message.header.frame_id) for s in got] == [
        ("robot1/alliance/inter_robot_communication", "robot1")]
    assert got[0].type_name == "alliance_msgs/InterRobotCommunication"


def test_double_star_matches_any_depth():
    bus = InProcBus()
    got = []
    bus.subscribe("robot1/**", got.append)
    bus.publish("robot1/cmd_vel", Twist(0.0, 0.0))
    bus.publish("robot1/alliance/motivation/wander", irc("robot1"))
    bus.publish("robot2/cmd_vel", Twist(0.0, 0.0))
    assert [s.key for s in got] == ["robot1/cmd_vel", "robot1/alliance/motivation/wander"]


def test_queue_size_keeps_the_newest():
    bus = InProcBus()
    sub = bus.subscribe("k", queue_size=3)
    for i in range(10):
        bus.publish("k", irc("r", i))
    seqs = [sub.get(timeout=0.1).message.header.seq for _ in range(3)]
    assert seqs == [7, 8, 9]
    assert sub.get(timeout=0.01) is None


def test_malformed_samples_are_counted_and_dropped_with_a_warning(caplog):
    bus = InProcBus()
    got = []
    sub = bus.subscribe("k", got.append)
    with caplog.at_level(logging.WARNING, logger="mrta.bus"):
        for _ in range(5):
            bus.publish_raw("k", encoding_for("alliance_msgs/InterRobotCommunication"), b"\xc1")
        bus.publish("k", irc("good"))
    assert [s.message.header.frame_id for s in got] == ["good"]
    assert sub.malformed == 5 and bus.stats["malformed"] == 5
    warnings = [r for r in caplog.records if "malformed" in r.getMessage()]
    assert len(warnings) == 1  # rate limited


def test_type_filter_ignores_other_types():
    bus = InProcBus()
    got = []
    sub = bus.subscribe("k", got.append, msg_type=InterRobotCommunication)
    bus.publish("k", Twist(1.0, 1.0))
    bus.publish("k", irc("r"))
    assert len(got) == 1 and sub.wrong_type == 1


def test_handler_exceptions_do_not_break_delivery():
    bus = InProcBus()
    got = []

    def bad(sample):
        raise RuntimeError("boom")

    bus.subscribe("k", bad)
    bus.subscribe("k", got.append)
    bus.publish("k", irc("r"))
    assert len(got) == 1 and bus.stats["handler_errors"] == 1


def test_liveliness_between_two_buses_on_one_network():
    net = InProcNetwork()
    a, b = InProcBus(net), InProcBus(net)
    events = []
    b.watch_liveliness("robot1/**", lambda k, alive: events.append((k, alive)))
    a.declare_token("robot1/alliance/agent")
    a.close()  # a process exit takes its tokens with it
    assert events == [("robot1/alliance/agent", True), ("robot1/alliance/agent", False)]


def test_liveliness_history_reports_existing_tokens():
    net = InProcNetwork()
    a, b = InProcBus(net), InProcBus(net)
    a.declare_token("simulator")
    events = []
    b.watch_liveliness("**", lambda k, alive: events.append((k, alive)))
    assert events == [("simulator", True)]


def test_namespace_isolates_and_is_invisible_to_handlers():
    net = InProcNetwork()
    team_a, team_b, plain = InProcBus(net, "teamA"), InProcBus(net, "teamB"), InProcBus(net)
    got_a, got_b, got_plain = [], [], []
    team_a.subscribe("robot1/cmd_vel", got_a.append)
    team_b.subscribe("robot1/cmd_vel", got_b.append)
    plain.subscribe("**", got_plain.append)
    team_a.publish("robot1/cmd_vel", Twist(1.0, 0.0))
    assert [s.key for s in got_a] == ["robot1/cmd_vel"]
    assert got_b == []
    assert [s.key for s in got_plain] == ["teamA/robot1/cmd_vel"]


def test_generic_messages_from_other_clients():
    bus = InProcBus()
    got = []
    bus.subscribe("k", got.append)
    bus.publish_raw("k", encoding_for("vendor_msgs/Battery"), msgpack.packb({"level": 0.5}))
    assert got[0].message.data == {"level": 0.5} and got[0].type_name == "vendor_msgs/Battery"


def test_handler_with_queue_runs_on_a_worker():
    import threading
    bus = InProcBus()
    done = threading.Event()
    seen = []

    def handler(s):
        seen.append(threading.current_thread().name)
        done.set()

    bus.subscribe("k", handler, queue_size=5)
    bus.publish("k", irc("r"))
    assert done.wait(2.0)
    assert seen[0].startswith("mrta-sub:")
    bus.close()


def test_lockstep_counting_has_one_owner_and_counts_what_it_should():
    """Bus.enable_counting: samples published per key (not lockstep's own `@` keys) and, per
    decoded subscription, samples taken into account — after its handler; one owner, whose
    callback runs per counted sample; closed, the bus counts nothing until another owner
    starts from zero."""
    from mrta_zenoh.errors import MrtaRuntimeError
    from mrta_zenoh.messages import Twist

    net = InProcNetwork()
    bus, other = InProcBus(net), InProcBus(net)
    before = bus.subscribe("robot2/*", lambda s: None, msg_type=Twist)  # before counting
    raw = bus.subscribe_raw("robot2/**", lambda s: None)
    pokes, seen_by_handler = [], []
    counts = bus.enable_counting(lambda: pokes.append(1))
    after = bus.subscribe("robot2/cmd_vel",
                          lambda s: seen_by_handler.append(counts.received(after)[s.key]),
                          msg_type=Twist)
    with pytest.raises(MrtaRuntimeError):
        bus.enable_counting()
    bus.publish("robot1/cmd_vel", Twist(0.0, 0.0))
    bus.publish("@mrta/lockstep/step/x", Twist(0.0, 0.0))
    other.publish("robot2/cmd_vel", Twist(0.0, 0.0))
    other.publish("robot2/cmd_vel", Twist(0.0, 0.0))
    assert counts.sent == {"robot1/cmd_vel": 1}
    assert counts.received(before) == counts.received(after) == {"robot2/cmd_vel": 2}
    assert seen_by_handler == [0, 1]           # counted once its handler has run
    assert [t.key_expr for t in counts.tallies()] == ["robot2/*", "robot2/cmd_vel"]
    with pytest.raises(ValueError):
        counts.received(raw)                   # raw subscriptions count nothing
    assert len(pokes) == 4                     # two samples, two counting subscriptions
    counts.close()
    other.publish("robot2/cmd_vel", Twist(0.0, 0.0))
    assert len(pokes) == 4
    again = bus.enable_counting()
    assert again.sent == {} and again.received(before) == {}
    bus.close()
    other.close()
