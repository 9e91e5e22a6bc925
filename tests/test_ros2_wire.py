"""ROS 2 over rmw_zenoh, byte for byte: fixed vectors for type hashes, keys, liveliness tokens,
QoS strings, CDR and attachments (mrta_zenoh.ros2.names / types / attachment)."""

import math
import struct

import pytest

from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
from mrta_zenoh.ros2 import names
from mrta_zenoh.ros2.attachment import Attachment, AttachmentError, Stamper
from mrta_zenoh.ros2.names import BEST_EFFORT, COMMANDS, SENSOR_DATA, Qos, Ros2NameError
from mrta_zenoh.ros2.types import Ros2Types

TWIST_HASH = "RIHS01_9c45bf16fe0983d80e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a"


@pytest.fixture(scope="module")
def types():
    return Ros2Types("jazzy")


@pytest.mark.parametrize("ros_type, prefix", [
    ("geometry_msgs/msg/Twist", "RIHS01_9c45bf16"),
    ("nav_msgs/msg/Odometry", "RIHS01_3cc97dc7"),
    ("sensor_msgs/msg/LaserScan", "RIHS01_64c19139"),
    ("sensor_msgs/msg/PointCloud2", "RIHS01_9198cabf"),
])
def test_type_hashes_match_the_published_ones(types, ros_type, prefix):
    h = types.hash(ros_type)
    assert h.startswith(prefix) and len(h) == len("RIHS01_") + 64


def test_humble_keys_carry_no_hash_as_rmw_zenoh_humble_writes_them():
    assert Ros2Types("humble").hash("geometry_msgs/msg/Twist") == "TypeHashNotSupported"


def test_topic_key_of_a_robot_cmd_vel(types):
    key = names.topic_key(0, "/robot1/cmd_vel", "geometry_msgs/msg/Twist",
                          types.hash("geometry_msgs/msg/Twist"))
    assert key == f"0/robot1/cmd_vel/geometry_msgs::msg::dds_::Twist_/{TWIST_HASH}"
    assert names.dds_type("nav_msgs/msg/Odometry") == "nav_msgs::msg::dds_::Odometry_"
    assert names.ros_type("nav_msgs::msg::dds_::Odometry_") == "nav_msgs/msg/Odometry"


def test_qos_strings_leave_defaults_empty_and_always_write_the_depth():
    assert COMMANDS.encode() == "::,10:,:,:,,"
    assert SENSOR_DATA.encode() == "2::,5:,:,:,,"
    assert Qos(durability=names.TRANSIENT_LOCAL, depth=1).encode() == ":1:,1:,:,:,,"
    for q in (COMMANDS, SENSOR_DATA, Qos(BEST_EFFORT, names.TRANSIENT_LOCAL, names.KEEP_LAST, 7)):
        assert Qos.decode(q.encode()) == q
    with pytest.raises(Ros2NameError):
        Qos.decode("1:2:1")


def test_liveliness_tokens_escape_slashes_and_empty_fields(types):
    node = names.node_token(0, "a1b2", 3, "/robot1", "pioneer_driver")
    assert node == "@ros2_lv/0/a1b2/3/3/NN/%/%robot1/pioneer_driver"
    root = names.node_token(7, "a1b2", 3, "/", "mrta_bridge")
    assert root == "@ros2_lv/7/a1b2/3/3/NN/%/%/mrta_bridge"
    pub = names.endpoint_token(0, "a1b2", 3, 4, "MP", "/", "mrta_bridge", "/robot1/cmd_vel",
                               "geometry_msgs/msg/Twist", TWIST_HASH, COMMANDS)
    assert pub == ("@ros2_lv/0/a1b2/3/4/MP/%/%/mrta_bridge/%robot1%cmd_vel/"
                   f"geometry_msgs::msg::dds_::Twist_/{TWIST_HASH}/::,10:,:,:,,")
    e = names.parse_token(pub)
    assert (e.kind, e.namespace, e.node, e.topic, e.type, e.type_hash, e.qos) == \
        ("MP", "/", "mrta_bridge", "/robot1/cmd_vel", "geometry_msgs/msg/Twist", TWIST_HASH,
         COMMANDS)
    n = names.parse_token(node)
    assert (n.kind, n.node_name) == ("NN", "/robot1/pioneer_driver")


@pytest.mark.parametrize("bad", [
    "@ros2_lv/0/z/1/1/XX/%/%/n",                    # unknown kind
    "@ros2_lv/x/z/1/1/NN/%/%/n",                    # domain not a number
    "@ros2_lv/0/z/1/2/MP/%/%/n/%t",                 # endpoint cut short
    "robot1/alliance/agent",                        # not ours to parse
])
def test_tokens_that_do_not_parse_say_why(bad):
    with pytest.raises(Ros2NameError):
        names.parse_token(bad)


def test_names_are_resolved_like_ros_and_bad_ones_refused():
    assert names.resolve("/robot1", "cmd_vel") == "/robot1/cmd_vel"
    assert names.resolve("/robot1", "/abs/odom") == "/abs/odom"
    assert names.normalize_namespace("robot1/") == "/robot1"
    for bad in ("robot 1", "a//b", "1abc"):
        with pytest.raises(Ros2NameError):
            names.resolve("/", bad)


def test_cdr_bytes_of_a_twist_are_rosbags_own_and_the_little_endian_layout(types):
    ours = types.serialize(types.twist_to_ros(Twist(1.0, 0.5)), "geometry_msgs/msg/Twist")
    assert ours[:4] == b"\x00\x01\x00\x00"
    assert ours == b"\x00\x01\x00\x00" + struct.pack("<6d", 1.0, 0, 0, 0, 0, 0.5)
    direct = types.store.types["geometry_msgs/msg/Twist"](
        types.store.types["geometry_msgs/msg/Vector3"](1.0, 0.0, 0.0),
        types.store.types["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.5))
    assert ours == bytes(types.store.serialize_cdr(direct, "geometry_msgs/msg/Twist"))


def test_odometry_round_trips_through_cdr(types):
    ours = Odometry(Header("robot1/odom", 12.25, 3), Pose2D(1.5, -2.0, 2.5), Twist(0.3, -0.1))
    data = types.serialize(types.odometry_to_ros(ours), "nav_msgs/msg/Odometry")
    back = types.odometry_from_ros(types.deserialize(data, "nav_msgs/msg/Odometry"),
                                   "robot1/odom", 3)
    assert back.header == ours.header
    assert back.pose.x == 1.5 and back.pose.y == -2.0
    assert back.pose.theta == pytest.approx(2.5, abs=1e-12)
    assert back.twist == ours.twist


@pytest.mark.parametrize("kind", ["pointcloud", "pointcloud2", "laserscan"])
def test_sonar_round_trips_in_each_ros_type(types, kind):
    pts = (Point2D(1.0, 0.0), Point2D(0.0, 2.0), Point2D(-1.5, -1.5))
    ours = PointCloud(Header("robot1/sonar", 4.0, 1), pts)
    ros_type = {"pointcloud": "sensor_msgs/msg/PointCloud",
                "pointcloud2": "sensor_msgs/msg/PointCloud2",
                "laserscan": "sensor_msgs/msg/LaserScan"}[kind]
    data = types.serialize(types.sonar_to_ros(ours, kind), ros_type)
    back = types.sonar_from_ros(types.deserialize(data, ros_type), kind, "robot1/sonar", 1)
    assert back.header.stamp == 4.0 and len(back.points) == 3
    tol = 1e-6 if kind != "laserscan" else 2 * math.pi / 360 * 2.2  # one-degree bins
    for a, b in zip(sorted(pts, key=lambda p: math.atan2(p.y, p.x)),
                    sorted(back.points, key=lambda p: math.atan2(p.y, p.x))):
        assert math.hypot(a.x - b.x, a.y - b.y) <= tol


def test_attachment_is_33_bytes_sequence_from_1_and_one_gid_per_publisher():
    s = Stamper()
    a1, a2 = s.next(1_000), s.next(2_000)
    assert len(a1) == 33 and a1[16] == 0x10
    p1, p2 = Attachment.unpack(a1), Attachment.unpack(a2)
    assert (p1.sequence, p2.sequence) == (1, 2) and p1.gid == p2.gid == s.gid
    assert (p1.timestamp_ns, p2.timestamp_ns) == (1_000, 2_000)
    assert a1 == struct.pack("<qqB", 1, 1_000, 16) + s.gid
    assert Stamper().gid != s.gid


@pytest.mark.parametrize("data, message", [
    (None, "no attachment"),
    (b"\x00" * 77, "early-Jazzy"),
    (struct.pack("<qqB", 1, 1, 8) + b"\x00" * 16, "GID length byte is 8"),
])
def test_bad_attachments_are_refused_with_the_reason(data, message):
    with pytest.raises(AttachmentError, match=message):
        Attachment.unpack(data)


@pytest.mark.parametrize("args, message", [
    (["ros2", "bridge", "--robot", "robot1", "--robot", "robot2", "--ros-namespace", "/r"],
     "one --robot"),
    (["ros2", "bridge", "--robot", "robot1", "--ros-namespace", "bad name"], "namespace"),
    (["ros2", "bridge", "--robot", "robot1", "--cmd-vel", "cmd vel"], "cmd vel"),
    (["sim", "--world", "patrol", "--robot", "robot1", "--ros2", "robot9"], "robot9"),
    (["sim", "--world", "patrol", "--robot", "robot1", "--ros2", "robot1", "--lockstep"],
     "exclude each other"),
])
def test_bad_ros2_options_exit_2_before_any_bus_opens(args, message):
    from click.testing import CliRunner

    from mrta_zenoh.cli.main import cli

    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 2, res.output
    assert message in res.output
