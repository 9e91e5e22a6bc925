"""`mrta launch`: the roslaunch subset, its errors, and running nodes as child processes."""

import os
import signal
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.toolchain.launchfile import (MAX_DEPTH, MAX_INCLUDES, MAX_NODES, MAX_TEXT,
                                             LaunchEvaluator, check_executables)
from mrta_zenoh.keys import matches
from tests.harness.helpers import REFERENCE


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


def _chain(tmp_path, n: int, fanout: int, last: str) -> Path:
    """f1.launch … f{n}.launch, each including the next `fanout` times; the last holds `last`."""
    for i in range(1, n):
        includes = f'<include file="{tmp_path}/f{i + 1}.launch"/>' * fanout
        write(tmp_path, f"<launch>\n{includes}\n</launch>\n", f"f{i}.launch")
    write(tmp_path, f"<launch>\n{last}\n</launch>\n", f"f{n}.launch")
    return tmp_path / "f1.launch"


def test_an_include_bomb_is_refused_at_the_depth_bound_naming_the_chain(tmp_path):
    """Twenty files of under 200 bytes, each including the next twice: 2^19 includes. The
    evaluation stops at MAX_DEPTH, naming the include that went too deep and the chain."""
    top = _chain(tmp_path, 20, 2, '<node pkg="simulator" type="sim"/>')
    assert all(f.stat().st_size - 2 * len(str(tmp_path)) < 200 for f in tmp_path.iterdir())
    res = CliRunner().invoke(cli, ["launch", str(top), "--dry-run"])
    assert res.exit_code == 2, res.output
    (line,) = res.output.strip().splitlines()
    deepest = tmp_path / f"f{MAX_DEPTH}.launch"
    assert line.startswith(f"Error: {deepest}:2: <include>: includes nest more than "
                           f"{MAX_DEPTH} deep (included from "), line
    assert f"f{MAX_DEPTH - 1}.launch:2 ← " in line and line.endswith(f"← {top}:2)")


def test_a_wide_include_bomb_is_refused_at_the_count_bound(tmp_path):
    """Within the depth bound, but 3^11 includes: refused when the count passes the bound,
    long before it would have expanded them all."""
    top = _chain(tmp_path, 12, 3, '<arg name="x" default="1"/>')
    with pytest.raises(ConfigError, match=f"more than {MAX_INCLUDES:,} includes") as err:
        evaluate(top)
    assert "included from" in str(err.value)


def test_nodes_are_bounded(tmp_path):
    nodes = '<node pkg="simulator" type="sim"/>' * 40
    top = _chain(tmp_path, 3, 30, nodes)  # 30 × 30 × 40 = 36,000 nodes
    with pytest.raises(ConfigError, match=f"more than {MAX_NODES:,} nodes"):
        evaluate(top)


def test_an_argument_doubled_into_a_huge_string_is_refused(tmp_path):
    args = "".join(f'<arg name="a{i + 1}" default="$(arg a{i})$(arg a{i})"/>' for i in range(60))
    f = write(tmp_path, f'<launch>\n<arg name="a0" default="{"x" * 64}"/>\n{args}\n</launch>')
    with pytest.raises(ConfigError, match=f"longer than {MAX_TEXT:,} characters") as err:
        evaluate(f)
    assert err.value.line == 3


def test_an_error_in_an_included_file_names_where_it_was_included(tmp_path):
    write(tmp_path, '<launch>\n\n<node pkg="simulator" typ="sim"/>\n</launch>', "inner.launch")
    write(tmp_path, '<launch>\n<include file="$(find here)/inner.launch"/>\n</launch>',
          "middle.launch")
    top = write(tmp_path, '<launch>\n<group ns="a">\n<include file="$(find here)/middle.launch"/>'
                          "\n</group>\n</launch>")
    with pytest.raises(ConfigError) as err:
        evaluate(top)
    assert err.value.file == str(tmp_path / "inner.launch") and err.value.line == 3
    assert str(err.value).endswith(f"unexpected attribute 'typ' (did you mean 'type'?) "
                                   "(allowed: args, cwd, name, ns, output, pkg, required, "
                                   f"respawn, type) (included from {tmp_path}/middle.launch:2 "
                                   f"← {top}:3)"), str(err.value)
    # a sibling include that succeeded leaves no trace in a later error's chain
    write(tmp_path, "<launch/>", "ok.launch")
    top2 = write(tmp_path, '<launch>\n<include file="$(find here)/ok.launch"/>\n'
                           '<node pkg="simulator"/>\n</launch>', "top2.launch")
    with pytest.raises(ConfigError) as err:
        evaluate(top2)
    assert "included from" not in str(err.value) and err.value.line == 3


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


AGENT = ('<node name="agent" pkg="robot_agent" type="agent" ns="robot1" args="robot1 '
         '--robot-params {c}/robot1_alliance_params.yaml --tasks-params '
         '{c}/tasks_alliance_params.yaml --layers-params {c}/layers_alliance_params.yaml"/>')


def agent_node() -> str:
    from tests.harness.helpers import PATROL
    return AGENT.format(c=PATROL / "config")


def node_pid(launcher, word: str, timeout: float = 30) -> int:
    """The pid of the launcher's child whose command line holds `word` (from /proc)."""
    from tests.test_mission_hygiene import children_of
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        for pid in children_of(launcher.proc.pid):
            try:
                if word in open(f"/proc/{pid}/cmdline").read():
                    return pid
            except OSError:
                continue
        assert launcher.running(), launcher.tail(20)
        time.sleep(0.1)
    raise AssertionError(f"no child running {word}")


@pytest.mark.slow
@pytest.mark.multiprocess
def test_running_nodes_a_failure_is_reported_and_output_is_prefixed(children, tmp_path):
    """The broken agent is not required: it is reported and the launch goes on; the
    simulator, required, ends at its --duration and brings the launch down; exit 1."""
    f = write(tmp_path, """<launch>
      <node name="sim" pkg="simulator" type="sim" required="true"
            args="--world patrol --robot robot1 --speed 1 --duration 3"/>
      <node name="broken" pkg="robot_agent" type="agent"
            args="robot1 --robot-params /nonexistent.yaml --tasks-params /nonexistent.yaml"/>
    </launch>""")
    t0 = time.monotonic()
    launcher = children.mrta("launch", str(f), name="launch")
    assert launcher.wait(60) == 1
    assert time.monotonic() - t0 < 55
    out = launcher.stdout
    assert any(line.startswith("[broken] ") and "cannot read" in line for line in out), out
    err = launcher.stderr
    assert "[broken] exited with code 2" in err, err
    assert any(line.startswith("[sim] exited normally — a required node") for line in err), err
    assert err[-1] == "Error: 1 node failed: broken exited with code 2", err


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_required_node_killed_with_sigkill_is_reported_and_stops_the_launch(children, tokens,
                                                                               tmp_path):
    """kill -9 of the simulator must not go unnoticed: it is said, and the launch stops."""
    f = write(tmp_path, f"""<launch>
      <node name="sim" pkg="simulator" type="sim" required="true"
            args="--world patrol --robot robot1"/>
      {agent_node()}
    </launch>""")
    launcher = children.mrta("launch", str(f), name="launch")
    tokens.wait_all(["@mrta/clock_source/*", "robot1/alliance/agent"], 60, launcher)
    os.kill(node_pid(launcher, "simulator/sim"), signal.SIGKILL)
    assert launcher.wait(30) == 1, launcher.tail(20)
    err = launcher.stderr
    assert "[sim] killed by SIGKILL — a required node: stopping every node" in err, err
    assert "[robot1/agent] stopped" in err, err
    assert err[-1] == "Error: 1 node failed: sim killed by SIGKILL", err


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_node_killed_with_sigkill_is_reported_and_the_others_keep_running(children, tokens,
                                                                            tmp_path):
    f = write(tmp_path, f"""<launch>
      <node name="sim" pkg="simulator" type="sim" args="--world patrol --robot robot1"/>
      {agent_node()}
    </launch>""")
    launcher = children.mrta("launch", str(f), name="launch")
    tokens.wait_all(["@mrta/clock_source/*", "robot1/alliance/agent"], 60, launcher)
    os.kill(node_pid(launcher, "robot_agent/agent"), signal.SIGKILL)
    launcher.wait_stderr(lambda line: line == "[robot1/agent] killed by SIGKILL", 15)
    assert launcher.running()
    assert any(matches("@mrta/clock_source/*", k) for k in tokens.alive)  # the sim goes on
    launcher.signal(signal.SIGINT)
    assert launcher.wait(20) == 130, launcher.tail(20)
    assert "[sim] stopped" in launcher.stderr, launcher.stderr


@pytest.mark.slow
@pytest.mark.multiprocess
def test_ctrl_c_stops_every_node(children, tokens, tmp_path):
    """As a terminal does: SIGINT to the node and to the launch at once. The node's end is
    `stopped`, not `exited with code -2`, and the launch exits 130."""
    f = write(tmp_path, """<launch>
      <node name="sim" pkg="simulator" type="sim" args="--world patrol --robot robot1"/>
    </launch>""")
    launcher = children.mrta("launch", str(f), name="launch")
    tokens.wait("@mrta/clock_source/*", 30, launcher)  # the node is up
    os.kill(node_pid(launcher, "simulator/sim"), signal.SIGINT)
    launcher.signal(signal.SIGINT)
    assert launcher.wait(15) == 130
    assert "[sim] stopped" in launcher.stderr, launcher.stderr
    assert not any("code" in line for line in launcher.stderr), launcher.stderr
