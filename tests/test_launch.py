"""`mrta launch`: the roslaunch subset, its errors, and running nodes as child processes."""

import signal
import time

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.toolchain.launchfile import LaunchEvaluator, check_executables
from tests.helpers import REFERENCE


def write(tmp_path, text, name="x.launch"):
    f = tmp_path / name
    f.write_text(text)
    return f


def evaluate(path, **args):
    return LaunchEvaluator(lambda pkg: {"here": path.parent}[pkg]).run(path, args)


def test_args_includes_groups_env_and_substitutions(tmp_path):
    write(tmp_path, """<launch>
      <arg name="robot_id"/>
      <arg name="extra" default="--seed 3"/>
      <group ns="$(arg robot_id)">
        <node name="a" pkg="robot_agent" type="agent" args="$(arg robot_id) $(arg extra)">
          <param name="id" value="$(arg robot_id)"/>
          <rosparam file="$(find here)/p.yaml" command="load"/>
          <env name="X" value="$(optenv NOPE fallback)"/>
        </node>
      </group></launch>""", "inner.launch")
    top = write(tmp_path, """<launch>
      <arg name="who" default="robot9"/>
      <env name="COLOR" value="blue"/>
      <include file="$(find here)/inner.launch"><arg name="robot_id" value="$(arg who)"/></include>
    </launch>""")
    (node,) = evaluate(top, who="robot4")
    assert node.name == "robot4/a" and node.executable == "robot_agent/agent"
    assert node.args == ["robot4", "--seed", "3"]
    assert node.params == {"id": "robot4"} and node.rosparam_files == [f"{tmp_path}/p.yaml"]
    assert node.env == {"COLOR": "blue", "X": "fallback"}
    check_executables([node])


BAD = [
    ('<launch><node pkg="a" type="b" args="$(argg x)"/></launch>', 1, "unknown substitution $(argg x)"),
    ('<launch>\n<arg name="x"/>\n</launch>', 2, "required argument 'x' was not given"),
    ('<launch>\n<nod pkg="a" type="b"/></launch>', 2, "did you mean 'node'"),
    ('<launch>\n<node pkg="a" type="b" nmae="z"/></launch>', 2, "unexpected attribute 'nmae'"),
    ('<launch>\n<node pkg="robot_agent" type="agnt"/></launch>', 2, "no executable registered"),
    ('<launch>\n<node type="agent"/></launch>', 2, "missing attribute 'pkg'"),
    ('<launch>\n<include file="nowhere.launch"/></launch>', 2, "does not exist"),
    ('<launch>\n<node pkg="a" type="b" args="$(env MRTA_SURELY_UNSET)"/></launch>', 2, "variable not set"),
    ('<launch>\n<rosparam command="dump" file="f"/></launch>', 2, "only command=\"load\""),
    ('<launch>\n<node pkg="a" type="b" args="$(arg nope)"/></launch>', 2, "no such argument"),
]


@pytest.mark.parametrize("text,line,message", BAD, ids=[b[2] for b in BAD])
def test_malformed_launch_files_exit_2_with_file_and_line(tmp_path, text, line, message):
    f = write(tmp_path, text)
    with pytest.raises(ConfigError) as err:
        check_executables(evaluate(f))
    assert message in str(err.value) and err.value.line == line, str(err.value)
    res = CliRunner().invoke(cli, ["launch", str(f), "--dry-run"])
    assert res.exit_code == 2 and f"{f}:{line}" in res.output


def test_undeclared_argument_is_refused(tmp_path):
    f = write(tmp_path, '<launch><arg name="robot_id" default="r"/></launch>')
    res = CliRunner().invoke(cli, ["launch", str(f), "robt_id:=x", "--dry-run"])
    assert res.exit_code == 2 and "did you mean 'robot_id'" in res.output


def test_reference_launch_files_parse_and_name_what_is_missing(reference, tmp_path):
    f = REFERENCE / "alliance_test" / "launch" / "multiple_robots.launch"
    # the reference folder flattens alliance/launch/alliance.launch; rebuild the package layout
    (tmp_path / "alliance" / "launch").mkdir(parents=True)
    (tmp_path / "alliance" / "launch" / "alliance.launch").write_bytes(
        (REFERENCE / "alliance" / "alliance.launch").read_bytes())
    finder = {"alliance_test": REFERENCE / "alliance_test", "alliance": tmp_path / "alliance"}
    nodes = LaunchEvaluator(lambda p: finder[p]).run(f, {})
    assert [n.name for n in nodes][:3] == ["robot1/alliance/high_level", "robot1/alliance/low_level",
                                           "robot1/RosAria"]
    assert len(nodes) == 5 * 3 + 1
    with pytest.raises(ConfigError, match="no executable registered for pkg='alliance'"):
        check_executables(nodes)


@pytest.mark.multiprocess
def test_running_nodes_a_failure_stops_the_others_and_output_is_prefixed(children, tmp_path):
    f = write(tmp_path, """<launch>
      <node name="sim" pkg="simulator" type="sim" args="--world patrol --robot robot1 --speed 1"/>
      <node name="broken" pkg="robot_agent" type="agent"
            args="robot1 --robot-params /nonexistent.yaml --tasks-params /nonexistent.yaml"/>
    </launch>""")
    t0 = time.monotonic()
    launcher = children.mrta("launch", str(f), name="launch")
    assert launcher.wait(30) == 1
    assert time.monotonic() - t0 < 25
    out = launcher.stdout
    assert any(line.startswith("[broken] ") and "cannot read" in line for line in out), out
    assert any(line.startswith("[sim] exited") for line in out), out  # stopped by the failure


@pytest.mark.multiprocess
def test_ctrl_c_stops_every_node(children, tokens, tmp_path):
    f = write(tmp_path, """<launch>
      <node name="sim" pkg="simulator" type="sim" args="--world patrol --robot robot1"/>
    </launch>""")
    launcher = children.mrta("launch", str(f), name="launch")
    tokens.wait("@mrta/clock_source/*", 30, launcher)  # the node is up
    launcher.signal(signal.SIGINT)
    assert launcher.wait(15) == 0
    assert any("[sim] exited with code 0" in line for line in launcher.stdout)
