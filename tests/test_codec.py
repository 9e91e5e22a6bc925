import math

import msgpack
import pytest

from mrta_zenoh import codec

from mrta_zenoh.messages import Clock, GenericMessage, Header, Odometry, Point2D, PointCloud, Pose2D, Twist, registered_types
from mrta_agent.alliance.messages import InterRobotCommunication, Motivation, SensoryFeedback
from mrta_simulator.messages import Bumper, Segment, World
from mrta_patrol.messages import PatrolLog, Report, TaskTime
from mrta_delivery.messages import TaskEvent
from mrta_zenoh.lockstep.protocol import LockstepStatus, Step, StepDone
from mrta_agent.murdoch.messages import Announcement, Award, Bid, Claim, Release, Revoke
from mrta_agent.central.messages import Plan, Queue
from mrta_agent.route.messages import Progress, Queued
from mrta_agent.ssi.messages import Bid as SsiBid, Round
from mrta_agent.cbba.messages import Bids
from mrta_zenoh.fault_roles import Assigned
from mrta_zenoh.fault_tally import FaultTally
from mrta_zenoh.refusal_tally import RefusedTally
from mrta_zenoh.tasks.messages import Answer, Change, Request

EXAMPLES = [
    Header("robot1", 12.5, 7),
    TaskEvent(Header("robot1", 1.0, 1), "t1", "done"),
    Clock(3.25),
    Assigned(Header("robot2", 4.5, 1), "t3"),
    FaultTally(Header("robot2", 4.5, 1), lost=3, delayed=40, cut_off=2, out_of_range=1),
    RefusedTally(Header("dispatcher", 4.5, 1), ("progress",), ("robot2",), ("not_granted",), (1,),
                 (3,)),
    Pose2D(1.0, -2.0, math.pi / 3),
    Twist(0.4, -0.2),
    Odometry(Header("robot2", 1.0, 1), Pose2D(1.0, 2.0, 0.5), Twist(0.1, 0.2)),
    Point2D(0.5, -0.5),
    PointCloud(Header("robot3", 2.0, 2), tuple(Point2D(i * 0.1, -i * 0.1) for i in range(16))),
    InterRobotCommunication(Header("robot1", 5.0, 3), "wander", 100.0),
    Motivation(Header("robot1", 5.0, 3), "report", 6.0, True, False, True, True, 42.0, 250.0, False),
    SensoryFeedback(Header("robot1", 5.0, 3), "border_protection", True),
    Bumper(Header("robot2", 7.5, 4), True, True, 3),
    TaskTime("robot1", "wander", 12.5),
    Report(Header("robot3", 9.0, 1), 42.0, 0.5, (TaskTime("robot1", "wander", 12.5),)),
    PatrolLog(Header("robot2", 5.0, 3), 12.5, 208, bytes(26), (TaskTime("robot2", "wander", 4.0),)),
    Clock(3.25, "run-a"),
    Step(12.5, 625, bytes(range(16)), ["robot1/alliance/inter_robot_communication"], 1, bytes(16)),
    StepDone("robot1", 12.5, {"robot1/cmd_vel": 125}, 12.6),
    LockstepStatus(30.0, ("robot2",)),
    Segment(0.0, 0.0, 1.0, 2.0),
    World(Header("world", 1.0, 0), "patrol", (Segment(-20.0, -6.0, 20.0, -6.0),)),
    Announcement(Header("robot1", 3.0, 1), 7, "report", ("odom", "sonar"), 0.5),
    Bid(Header("robot3", 3.1, 1), "robot1", 7, "report", 0.84),
    Award(Header("robot1", 3.5, 2), 7, "report", "robot3", 0.84),
    Claim(Header("robot3", 3.6, 1), "report", 3.6, 2.0),
    Release(Header("robot3", 20.0, 9), "report", "no progress for 3.0 s"),
    Revoke(Header("robot1", 61.0, 1), "t1", "robot3", 0.5, "no progress in 60 s"),
    Queue(Header("dispatcher", 4.0, 3), "robot2", 7, ("t3", "t1")),
    Progress(Header("robot2", 4.1, 9), "t3", "t5", ("t3", "t1"), ("t5",), 1.5, -2.0, 0.3, 7,
             True),  # central's: the queue version it applied, holding
    Plan(Header("dispatcher", 4.0, 2), 6, "completion", "minsum", 29.45, "kept", 0.75,
         ("robot2:t3,t1", "robot4:")),
    Round(Header("robot1", 4.0, 5), 3, (1, -1, -2, -3), 0, 2.5),
    SsiBid(Header("robot2", 4.1, 2), "robot1", 3, 1, 4.0, (3,)),
    Bids(Header("robot2", 4.1, 9), ((0, 1, 0.75),), ((0, 4.0), (1, 4.1)), (3,), 1.5, -2.0),
    Progress(Header("robot2", 4.1, 9), "t3", "t5", ("t3", "t1"), ("t5",), 1.5, -2.0, 0.3),
    Queued(Header("robot2", 4.1, 10), "t1", 1),
    Request(Header("ops", 1.0, 0), "r1", "submit", "n1", '{"position": [1, 2]}', 2),
    Answer(Header("tasks", 2.5, 3), "r1", "accepted", "n1", "", 2.5, ""),
    Change(Header("tasks", 2.5, 0), "submit", "n1", '{"position": [1, 2]}', 2, "ops"),
]


def own_types() -> set[str]:
    """The types this project registers: a package installed beside it (examples/ping_app, as
    the README has it) registers its own, which this file cannot have examples of (issue 51,
    the newcomer's list: installing ping_app made this test fail)."""
    from importlib.metadata import entry_points
    others = {ep.name for ep in entry_points(group="mrta.messages")
              if ep.dist is not None and ep.dist.name != "mrta-zenoh"}
    return set(registered_types()) - others


def test_every_registered_type_has_an_example():
    assert {type(m).TYPE_NAME for m in EXAMPLES} >= own_types()


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: m.TYPE_NAME)
def test_round_trip(msg):
    payload = codec.encode(msg)
    back = codec.decode(msg.TYPE_NAME, payload)
    assert back == msg
    assert type(back) is type(msg)


def test_wire_format_is_a_plain_msgpack_map():
    msg = InterRobotCommunication(Header("robot1", 1.5, 2), "wander", 100.0, 0.5)
    assert msgpack.unpackb(codec.encode(msg)) == {
        "header": {"frame_id": "robot1", "stamp": 1.5, "seq": 2},
        "task_id": "wander", "expected_duration": 100.0, "active_since": 0.5,
    }
    # a client that does not know active_since (the original alliance_msgs) is still understood
    old = msgpack.packb({"header": {"frame_id": "robot1", "stamp": 1.5, "seq": 2},
                         "task_id": "wander", "expected_duration": 100.0})
    assert codec.decode(msg.TYPE_NAME, old).active_since == -1.0
    assert codec.encoding_for(msg.TYPE_NAME) == "application/msgpack;alliance_msgs/InterRobotCommunication"


def test_integers_are_accepted_for_float_fields_from_other_clients():
    payload = msgpack.packb({"linear": 1, "angular": 0})
    msg = codec.decode("mrta_msgs/Twist", payload)
    assert msg == Twist(1.0, 0.0) and type(msg.linear) is float


def test_unknown_type_decodes_to_generic_message():
    msg = codec.decode("vendor_msgs/Battery", msgpack.packb({"level": 0.5, "cells": [1, 2]}))
    assert msg == GenericMessage("vendor_msgs/Battery", {"level": 0.5, "cells": [1, 2]})


IRC = "alliance_msgs/InterRobotCommunication"
GOOD = {"header": {"frame_id": "r1", "stamp": 1.0, "seq": 1}, "task_id": "t", "expected_duration": 1.0}


def _with(**changes):
    d = {k: (dict(v) if isinstance(v, dict) else v) for k, v in GOOD.items()}
    for k, v in changes.items():
        if "__" in k:
            a, b = k.split("__")
            if v is _DROP:
                del d[a][b]
            else:
                d[a][b] = v
        elif v is _DROP:
            del d[k]
        else:
            d[k] = v
    return msgpack.packb(d)


_DROP = object()

MALFORMED = [
    ("not msgpack", IRC, b"\xc1\xc1\xc1", codec.NotMsgpack, "invalid or reserved"),
    ("empty payload", IRC, b"", codec.TruncatedPayload, "ends in the middle"),
    ("truncated", IRC, msgpack.packb(GOOD)[:-5], codec.TruncatedPayload, "ends in the middle"),
    ("trailing bytes", IRC, msgpack.packb(GOOD) + b"\x01", codec.NotMsgpack, "trailing"),
    ("top level list", IRC, msgpack.packb([1, 2]), codec.NotAMap, "expected a map"),
    ("missing field", IRC, _with(task_id=_DROP), codec.MissingField, "task_id"),
    ("missing nested field", IRC, _with(header__seq=_DROP) , codec.MissingField, "header/seq"),
    ("extra field", IRC, msgpack.packb({**GOOD, "color": "red"}), codec.UnknownField, "color"),
    ("string for float", IRC, _with(expected_duration="long"), codec.WrongFieldType, "expected_duration"),
    ("bool for int", IRC, _with(header__seq=True), codec.WrongFieldType, "header/seq"),
    ("int for str", IRC, _with(task_id=3), codec.WrongFieldType, "task_id"),
    ("header not a map", IRC, _with(header="robot1"), codec.NotAMap, "header"),
    ("points not a list", "mrta_msgs/PointCloud",
     msgpack.packb({"header": GOOD["header"], "points": {"x": 1}}), codec.WrongFieldType, "points"),
    ("bad point", "mrta_msgs/PointCloud",
     msgpack.packb({"header": GOOD["header"], "points": [{"x": 1.0, "y": "n"}]}), codec.WrongFieldType,
     "points/0/y"),
    ("int map keys", IRC, b"\x81\x01\x02", codec.NotMsgpack, "map key"),
    ("oversized payload", IRC, b"\x00" * (codec.MAX_PAYLOAD_BYTES + 1), codec.PayloadTooLarge, "exceeds"),
    ("absurd array", "mrta_msgs/PointCloud",
     b"\x82" + msgpack.packb("header") + msgpack.packb(GOOD["header"]) + msgpack.packb("points")
     + b"\xdd\xff\xff\xff\xff",  # an array declaring 4 G elements: refused, nothing allocated
     codec.TruncatedPayload, "ends"),
    ("absurd declared length", IRC, b"\xdb\xff\xff\xff\xff", codec.TruncatedPayload, "ends"),
    ("NaN stamp", IRC, _with(header__stamp=float("nan")), codec.NonFinite, "header/stamp"),
    ("inf duration", IRC, _with(expected_duration=float("inf")), codec.NonFinite,
     "expected_duration"),
    ("NaN in a point", "mrta_msgs/PointCloud",
     msgpack.packb({"header": GOOD["header"], "points": [{"x": float("nan"), "y": 0.0}]}),
     codec.NonFinite, "points/0/x"),
    ("generic not a map", "vendor_msgs/X", msgpack.packb(3), codec.NotAMap, "expected a map"),
]


@pytest.mark.parametrize("name,type_name,payload,error,text", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_malformed_payloads_are_rejected_with_a_specific_error(name, type_name, payload, error, text):
    with pytest.raises(error) as info:
        codec.decode(type_name, payload)
    assert text in str(info.value)


@pytest.mark.parametrize("enc", ["application/json;alliance_msgs/X", "application/msgpack",
                                 "application/msgpack;", "text/plain"])
def test_foreign_encodings_are_rejected(enc):
    with pytest.raises(codec.BadEncoding):
        codec.type_from_encoding(enc)


def test_oversized_payload_is_refused_before_parsing():
    with pytest.raises(codec.PayloadTooLarge):
        codec.decode(IRC, b"\x00" * (codec.MAX_PAYLOAD_BYTES + 1))


@pytest.mark.multiprocess
def test_every_type_decodes_in_a_fresh_interpreter_whatever_was_imported():
    """The registry comes from entry points: a process that imported nothing but the codec still
    decodes an ALLIANCE and a patrol message to their classes, not to GenericMessage."""
    import subprocess
    import sys
    code = (
        "import sys\n"
        "from mrta_zenoh import codec\n"
        "from mrta_zenoh.messages import GenericMessage\n"
        "import msgpack\n"
        "assert not {'mrta_agent', 'mrta_patrol'} & set(sys.modules), sorted(sys.modules)\n"
        "h = {'frame_id': 'r', 'stamp': 1.0, 'seq': 1}\n"
        "a = codec.decode('alliance_msgs/InterRobotCommunication', msgpack.packb("
        "{'header': h, 'task_id': 't', 'expected_duration': 2.0}))\n"
        "b = codec.decode('patrol_msgs/Report', msgpack.packb({'header': h, 'distance': 1.0, "
        "'border_covered': 0.5, 'task_times': []}))\n"
        "print(type(a).__module__, type(b).__module__, isinstance(a, GenericMessage))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["mrta_agent.alliance.messages", "mrta_patrol.messages", "False"]
