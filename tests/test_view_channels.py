"""The channels `mrta view APP` advertises before any message: what the layout's
panels name is there as soon as a client connects."""

from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.viewer import known_channels


def test_the_applications_channels_are_known_before_any_message():
    app, _ = resolve_application("patrol")
    known = {topic: (schema[0], enc) for topic, schema, enc in known_channels(app)}
    for robot in ("robot1", "robot2", "robot3"):
        for task in app.tasks():
            assert known[f"{robot}/alliance/motivation/{task}"] == (
                "alliance_msgs/Motivation", "json")
        assert known[f"{robot}/alliance/inter_robot_communication"][1] == "json"
        assert known[f"/robots/{robot}/task"] == ("mrta.RobotTask", "json")
        assert known[f"/robots/{robot}/pose"] == ("foxglove.PoseInFrame", "protobuf")
        assert known[f"{robot}/sonar"] == ("mrta_msgs/PointCloud", "json")
    assert known["/world"] == ("foxglove.SceneUpdate", "protobuf")
    assert known["/supervisor/state"] == ("mrta.SupervisorSnapshot", "json")
    assert known["/supervisor/alarms"] == ("foxglove.Log", "protobuf")
