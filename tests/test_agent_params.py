import pytest
import yaml
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_agent.alliance.params import load_agent_params
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write


def test_all_reference_files_load_unchanged(reference):
    cfg = reference / "alliance_test" / "config"
    for i in range(1, 6):
        p = load_agent_params(cfg / f"robot{i}_alliance_params.yaml",
                              cfg / "tasks_alliance_params.yaml", cfg / "layers_alliance_params.yaml")
        assert [b.task_id for b in p.robot.behaviour_sets] == ["wander", "border_protection", "report"]
        assert p.layers.data["BorderProtection"]["x_max"] == 30
    r1 = load_agent_params(cfg / "robot1_alliance_params.yaml", cfg / "tasks_alliance_params.yaml")
    assert r1.robot.spin_rate == 2.0 and r1.robot.behaviour_sets[0].threshold == 150.0
    assert r1.robot.sensors[1].topic_name == "sonar"


def test_reference_robot3_gets_a_warning_naming_file_and_key(reference):
    cfg = reference / "alliance_test" / "config"
    p = load_agent_params(cfg / "robot3_alliance_params.yaml", cfg / "tasks_alliance_params.yaml")
    assert len(p.warnings) == 2
    assert "robot3_alliance_params.yaml:60" in p.warnings[0]
    assert "behaviour_set2/motivational_behaviour/acquiescence/yielding_delay" in p.warnings[0]
    # broadcasts leave on ticks: 0.7 Hz at 1 Hz spin is one every 2 s, and τ = 3 s < 2 × 2 s
    assert "robot3_alliance_params.yaml:4" in p.warnings[1] and "every 2 s" in p.warnings[1]


def _mutate(doc, path, value):
    d = doc
    for k in path[:-1]:
        d = d[k]
    if value is KeyError:
        del d[path[-1]]
    else:
        d[path[-1]] = value


MB = ("behaviour_sets", "behaviour_set0", "motivational_behaviour")
BAD = [
    (("timeout_duration",), 0.0, "timeout_duration must be > 0", "timeout_duration"),
    (("timeout_duration",), -1.0, "must be > 0", "timeout_duration"),
    (("spin_rate",), KeyError, "missing mandatory key 'spin_rate'", "spin_rate"),
    (("broadcast_rate",), 0, "broadcast_rate must be > 0", "broadcast_rate"),
    (MB + ("impatience", "fast_rate"), -5.0, "fast_rate must be > 0", "impatience/fast_rate"),
    (MB + ("threshold",), "high", "threshold must be a number", "threshold"),
    (("spin_rte",), 2.0, "unknown key 'spin_rte' (did you mean 'spin_rate'?)", "spin_rte"),
    (MB + ("acquiescence", "yielding_dely"), 2.0, "did you mean 'yielding_delay'", "yielding_dely"),
    (("sensors", "size"), 3, "size is 3 but 'sensor2' is missing", "sensors"),
    (MB + ("sensory_feedback", "sensors", "sensor0", "topic_name"), "sonr",
     "sensor topic 'sonr' is not among the robot's sensors", "topic_name"),
]


@pytest.mark.parametrize("path,value,text,key", BAD, ids=[b[2][:30] for b in BAD])
def test_invalid_robot_parameters_name_file_and_key(tmp_path, path, value, text, key):
    doc = robot_yaml([{"task": "a", "fast": 10.0}])
    _mutate(doc, path, value)
    rf = write(tmp_path / "robot1.yaml", doc)
    tf = write(tmp_path / "tasks.yaml", tasks_yaml(["a"]))
    with pytest.raises(ConfigError) as info:
        load_agent_params(rf, tf)
    msg = str(info.value)
    assert str(rf) in msg and text in msg and key in msg, msg
    # through the CLI: exit 2, one line
    result = CliRunner().invoke(cli, ["agent", "robot1", "--robot-params", str(rf), "--tasks-params", str(tf)])
    assert result.exit_code == 2, result.output
    assert text in result.output and len(result.output.strip().splitlines()) == 1


def test_unknown_key_in_tasks_file_and_unknown_task(tmp_path):
    rf = write(tmp_path / "r.yaml", robot_yaml([{"task": "a", "fast": 10.0}]))
    doc = tasks_yaml(["a"])
    doc["tasks"]["task0"]["layer"] = {"size": 0}
    tf = write(tmp_path / "t.yaml", doc)
    with pytest.raises(ConfigError, match=r"t.yaml:\d+: 'tasks/task0/layer': unknown key 'layer' \(did you mean 'layers'\?\)"):
        load_agent_params(rf, tf)
    tf2 = write(tmp_path / "t2.yaml", tasks_yaml(["b"]))
    with pytest.raises(ConfigError, match="behaviour set for task 'a' but the tasks file has b"):
        load_agent_params(rf, tf2)


@pytest.mark.parametrize("drop", ["sensors", "behaviour_sets"])
def test_missing_array_block_is_a_config_error(tmp_path, drop):
    doc = robot_yaml([{"task": "a", "fast": 10.0}])
    del doc[drop]
    rf = write(tmp_path / "r.yaml", doc)
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    with pytest.raises(ConfigError, match=rf"r.yaml: '{drop}': missing mandatory key '{drop}'"):
        load_agent_params(rf, tf)
    empty = write(tmp_path / "empty_tasks.yaml", {"other": 1})
    with pytest.raises(ConfigError, match="unknown key 'other'"):
        load_agent_params(write(tmp_path / "r2.yaml", robot_yaml([{"task": "a", "fast": 1.0}])), empty)


def test_invalid_yaml_names_the_line(tmp_path):
    rf = tmp_path / "r.yaml"
    rf.write_text("spin_rate: 2\nsensors: [\n")
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    with pytest.raises(ConfigError, match=r"r.yaml:\d+: invalid YAML"):
        load_agent_params(rf, tf)


def test_a_task_may_have_no_layers(tmp_path):
    rf = write(tmp_path / "r.yaml", robot_yaml([{"task": "a", "fast": 10.0}]))
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    assert yaml.safe_load(tf.read_text())["tasks"]["task0"]["layers"] == {"size": 0}
    assert load_agent_params(rf, tf).tasks["a"].layers == ()


def test_unknown_plugin_is_exit_2_listing_known_ones(tmp_path):
    doc = robot_yaml([{"task": "a", "fast": 10.0}])
    doc["sensors"]["sensor0"]["plugin_name"] = "alliance_test/odometri"
    rf = write(tmp_path / "r.yaml", doc)
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    result = CliRunner().invoke(cli, ["agent", "robot1", "--robot-params", str(rf), "--tasks-params", str(tf)],
                                env={"MRTA_RENDEZVOUS": "tcp/127.0.0.1:1"})
    assert result.exit_code == 2, result.output
    assert "did you mean 'alliance_test/odometry'" in result.output
    assert "alliance_test/point_cloud" in result.output
