import pytest

from mrta_zenoh.fieldpath import FieldPath, FieldPathError

from mrta_zenoh.messages import GenericMessage, Header, Odometry, Point2D, PointCloud
from mrta_agent.alliance.messages import InterRobotCommunication

IRC = InterRobotCommunication(Header("robot2", 3.0, 9), "border_protection", 200.0)
CLOUD = PointCloud(Header("robot1", 0.0, 0), (Point2D(1.0, 2.0), Point2D(3.0, 4.0)))


@pytest.mark.parametrize("path,value", [
    ("header/frame_id", "robot2"),
    ("/header/frame_id", "robot2"),
    ("task_id", "border_protection"),
    ("header/seq", 9),
])
def test_resolves_nested_fields(path, value):
    p = FieldPath.parse(path)
    p.validate(InterRobotCommunication)
    assert p.resolve(IRC) == value


def test_arrays_by_index():
    assert FieldPath.parse("points/1/x").resolve(CLOUD) == 3.0
    assert FieldPath.parse("points/0").resolve(CLOUD) == Point2D(1.0, 2.0)
    FieldPath.parse("points/1/x").validate(PointCloud)


def test_generic_messages_resolve_too():
    msg = GenericMessage("vendor/Status", {"robot": {"name": "r9"}, "levels": [1, 2, 3]})
    assert FieldPath.parse("robot/name").resolve(msg) == "r9"
    assert FieldPath.parse("levels/2").resolve(msg) == 3


def test_empty_path_is_the_whole_message():
    assert FieldPath.parse("/").resolve(IRC) is IRC


@pytest.mark.parametrize("path,cls,text", [
    ("header/frame", InterRobotCommunication, "no 'frame' in header; fields there: frame_id, stamp, seq"),
    ("heder/frame_id", InterRobotCommunication, "no 'heder' in (the message); fields there: header, task_id"),
    ("points/x", PointCloud, "it is a list: use an index"),
    ("task_id/x", InterRobotCommunication, "plain value"),
    ("pose/0", Odometry, "no 0 in pose"),
])
def test_validation_names_the_failing_part_and_what_exists(path, cls, text):
    with pytest.raises(FieldPathError) as info:
        FieldPath.parse(path).validate(cls)
    assert text in str(info.value)


def test_resolve_errors_name_the_part():
    with pytest.raises(FieldPathError, match=r"no 5 in points; it is a list of 2 items"):
        FieldPath.parse("points/5/x").resolve(CLOUD)
    with pytest.raises(FieldPathError, match=r"no 'age' in robot; fields there: name"):
        FieldPath.parse("robot/age").resolve(GenericMessage("v/S", {"robot": {"name": "x"}}))


@pytest.mark.parametrize("bad", ["a//b", "a/b/", "a/b c", "a/-1"])
def test_bad_syntax(bad):
    with pytest.raises(FieldPathError):
        FieldPath.parse(bad)
