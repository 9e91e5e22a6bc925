"""Bad input found by a tester: every case is one line on stderr naming the file and line (and
key), exit 2, and nothing runs — no traceback, no silent acceptance, no hang."""

import textwrap

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write
from tests.harness.helpers import free_port

def run(*args):
    """The command in-process; every case must fail before a bus opens (a private rendezvous
    all the same, and agents get --duration, so a case that wrongly passes still ends)."""
    return CliRunner().invoke(cli, list(map(str, args)),
                              env={"MRTA_RENDEZVOUS": f"tcp/127.0.0.1:{free_port()}"})


def agent_files(tmp_path, robot=None, tasks=None, layers_text=None):
    rf = write(tmp_path / "robot.yaml", robot or robot_yaml([{"task": "wander", "fast": 10.0}]))
    layers = ["patrol/wander", "patrol/border_protection", "patrol/report"]  # read every section
    tf = write(tmp_path / "tasks.yaml", tasks or tasks_yaml(["wander"], {"wander": layers}))
    args = ["agent", "robot1", "--robot-params", rf, "--tasks-params", tf, "--duration", "1"]
    if layers_text is not None:
        lf = tmp_path / "layers.yaml"
        lf.write_text(textwrap.dedent(layers_text))
        args += ["--layers-params", lf]
    return args


def assert_bad_input(result, *fragments):
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    line = result.output.strip().splitlines()[-1]
    for f in fragments:
        assert f in line, line


LAYERS = [
    ("sections as a list", "- Wander\n- Report\n", "layers.yaml", "mapping of layer sections"),
    ("a section as a string", "Wander: fast\n", "layers.yaml:1", "'Wander'"),
    ("a word for a number", "BorderProtection:\n  wall_range: far\n", "layers.yaml:2", "wall_range"),
    ("a word for a speed", "Wander: {speed: fast}\n", "layers.yaml:1", "Wander/speed"),
    ("an unknown key", "Wander:\n  sped: 0.5\n", "layers.yaml:2", "did you mean 'speed'"),
    ("NaN", "Wander:\n  speed: .nan\n", "layers.yaml:2", "finite"),
    ("a recursive alias", "Wander: &w\n  speed: *w\n", "layers.yaml:1", "anchors"),
    ("billion laughs", "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a]\n"
     "Wander: {speed: 0.5}\n", "layers.yaml:1", "anchors"),
    ("a duplicate key", "Wander:\n  speed: 0.5\n  speed: 0.7\n", "layers.yaml:3", "duplicate key"),
]


@pytest.mark.parametrize("text,where,what", [c[1:] for c in LAYERS], ids=[c[0] for c in LAYERS])
def test_layers_file(tmp_path, text, where, what):
    assert_bad_input(run(*agent_files(tmp_path, layers_text=text)), where, what)


def _robot(**top):
    doc = robot_yaml([{"task": "wander", "fast": 10.0}])
    doc.update(top)
    return doc


ROBOT = [
    ("spin_rate NaN", {"spin_rate": float("nan")}, "spin_rate", "finite"),
    ("timeout inf", {"timeout_duration": float("inf")}, "timeout_duration", "finite"),
    ("spin_rate 1e-9", {"spin_rate": 1e-9}, "spin_rate", "between"),
    ("τ shorter than a tick", {"spin_rate": 1.0, "timeout_duration": 0.4}, "timeout_duration",
     "tick period"),
    # finite but absurd: each is refused with the line and the range
    ("timeout 1e308", {"timeout_duration": 1e308}, "timeout_duration",
     "must be between 0.001 and 86400 s (a millisecond to a day), got 1e+308"),
    ("buffer_horizon 1e308", {"buffer_horizon": 1e308}, "buffer_horizon", "and 86400 s"),
    ("max_expected_duration 1e308", {"max_expected_duration": 1e308}, "max_expected_duration",
     "and 86400 s"),
]


@pytest.mark.parametrize("top,key,what", [c[1:] for c in ROBOT], ids=[c[0] for c in ROBOT])
def test_robot_file(tmp_path, top, key, what):
    assert_bad_input(run(*agent_files(tmp_path, robot=_robot(**top))), "robot.yaml:", key, what)


@pytest.mark.parametrize("field,value", [("threshold", float("inf")), ("fast_rate", float("inf"))])
def test_infinite_thresholds_and_rates(tmp_path, field, value):
    doc = robot_yaml([{"task": "wander", "fast": 10.0}])
    mb = doc["behaviour_sets"]["behaviour_set0"]["motivational_behaviour"]
    (mb["impatience"] if field == "fast_rate" else mb)[field] = value
    assert_bad_input(run(*agent_files(tmp_path, robot=doc)), "robot.yaml:", field, "finite")


ABSURD_SET = [
    ("task_expected_duration", 1e308, "and 86400 s"),
    ("threshold", 1e-300, "threshold must be between 0.001 and 1000000 (motivation units)"),
    ("threshold", 1e308, "got 1e+308"),
    ("fast_rate", 1e308, "fast_rate must be between 1e-06 and 1000000 per tick"),
    ("yielding_delay", 1e308, "and 86400 s"),
    ("giving_up_delay", 1e308, "and 86400 s"),
]


@pytest.mark.parametrize("field,value,what", ABSURD_SET, ids=[f"{c[0]} {c[1]:g}" for c in ABSURD_SET])
def test_finite_but_absurd_behaviour_set_values(tmp_path, field, value, what):
    doc = robot_yaml([{"task": "wander", "fast": 10.0}])
    bs = doc["behaviour_sets"]["behaviour_set0"]
    mb = bs["motivational_behaviour"]
    target = {"task_expected_duration": bs, "threshold": mb, "fast_rate": mb["impatience"],
              "yielding_delay": mb["acquiescence"], "giving_up_delay": mb["acquiescence"]}[field]
    target[field] = value
    if field == "yielding_delay":  # keep it below giving_up_delay's own check
        mb["acquiescence"]["giving_up_delay"] = 80_000.0
    assert_bad_input(run(*agent_files(tmp_path, robot=doc)), "robot.yaml:", field, what)


def test_the_documented_ranges_are_the_ones_enforced():
    from mrta_zenoh.limits import ranges_table
    from tests.harness.helpers import ROOT

    assert ranges_table() in (ROOT / "docs" / "toolchain.md").read_text()


@pytest.mark.parametrize("task", ["border protection", "wan*der", "x" * 65])
def test_task_ids_are_checked_when_the_files_load(tmp_path, task):
    robot = robot_yaml([{"task": task, "fast": 10.0}])
    assert_bad_input(run(*agent_files(tmp_path, robot=robot, tasks=tasks_yaml([task]))),
                     "robot.yaml:", "task_id", "one key chunk")
    ok_robot = robot_yaml([{"task": "wander", "fast": 10.0}])
    assert_bad_input(run(*agent_files(tmp_path, robot=ok_robot, tasks=tasks_yaml([task]))),
                     "tasks.yaml:", "one key chunk")


def test_an_unknown_layer_plugin_names_the_file_and_line(tmp_path):
    tasks = tasks_yaml(["wander"], {"wander": ["patrol/wandr"]})
    assert_bad_input(run(*agent_files(tmp_path, tasks=tasks)), "tasks.yaml:", "patrol/wandr",
                     "did you mean 'patrol/wander'")


WORLDS = [
    ("yaml NaN", "w.yaml", "name: w\nwalls:\n  - segment: [0, 0, .nan, 1]\n", "w.yaml:3", "finite"),
    ("yaml inf start", "w.yaml", "name: w\nwalls:\n  - segment: [0, 0, 1, 1]\nrobots:\n"
     "  robot1: [.inf, 0, 0]\n", "w.yaml:5", "finite"),
    ("map NaN", "w.map", "2D-Map\nLINES\n0 0 nan 100\n", "w.map:3", "finite"),
    ("map inf home", "w.map", "2D-Map\nCairn: RobotHome inf 0 0\n", "w.map:2", "RobotHome"),
    # finite but absurd: a wall at 1e308 m overflowed the ray caster
    ("yaml wall 1e308", "w.yaml", "name: w\nwalls:\n  - segment: [0, 0, 1.0e+308, 1]\n",
     "w.yaml:3", "a coordinate must be between -10000 and 10000 m"),
    ("yaml border far", "w.yaml", "name: w\nwalls:\n  - segment: [0, 0, 1, 1]\n"
     "border: [[0, 0], [0, 1], [20000, 0]]\n", "w.yaml:4", "got 20000"),
    ("yaml start far", "w.yaml", "name: w\nwalls:\n  - segment: [0, 0, 1, 1]\nrobots:\n"
     "  robot1: [-1.0e+200, 0, 0]\n", "w.yaml:5", "a coordinate must be between"),
    ("map wall 1e308", "w.map", "2D-Map\nLINES\n0 0 1e308 100\n", "w.map:3",
     "a coordinate must be between -10000 and 10000 m"),
    ("map home far", "w.map", "2D-Map\nCairn: RobotHome 1e12 0 0\n", "w.map:2", "got 1000000000"),
]


@pytest.mark.parametrize("name,text,where,what", [c[1:] for c in WORLDS], ids=[c[0] for c in WORLDS])
def test_worlds(tmp_path, name, text, where, what):
    (tmp_path / name).write_text(text)
    assert_bad_input(run("sim", "--world", tmp_path / name, "--robot", "r1=1,1", "--duration", 1),
                     where, what)


@pytest.mark.parametrize("args,what", [
    (["sim", "--world", "patrol", "--robot", "robot1", "--duration", "nan"], "finite"),
    (["sim", "--world", "patrol", "--robot", "robot1", "--speed", "inf"], "finite"),
    (["demo", "--duration", "nan"], "finite"),
    (["agent", "r1", "--robot-params", "x", "--tasks-params", "y", "--duration", "nan"], "finite"),
    (["supervise", "patrol", "--unattended-after", "-1"], "must be >"),
    (["supervise", "patrol", "--duration", "inf"], "finite"),
])
def test_cli_numbers_must_be_finite_and_in_range(args, what):
    assert_bad_input(run(*args), what)


def test_snapshot_into_a_missing_folder_fails_before_the_run(tmp_path):
    assert_bad_input(run("sim", "--world", "patrol", "--robot", "robot1", "--duration", 1000,
                         "--snapshot", tmp_path / "missing" / "w.png"), "missing", "does not exist")


@pytest.mark.slow
@pytest.mark.parametrize("target", [
    # an existing folder it cannot write in: found only once the bus is open (mrta record
    # opens the session before the file), so this case opens a real Zenoh session
    pytest.param("/proc/x.mcap", marks=pytest.mark.multiprocess),
    "/nonexistent/folder/x.mcap",
])
def test_record_to_an_unwritable_place(target):
    result = CliRunner().invoke(cli, ["record", "-o", target, "--duration", "1"],
                                env={"MRTA_RENDEZVOUS": f"tcp/127.0.0.1:{free_port()}"})
    assert_bad_input(result, "x.mcap")


def test_launch_args_with_an_unbalanced_quote(tmp_path):
    f = tmp_path / "q.launch"
    f.write_text('<launch>\n  <node name="n" pkg="robot_agent" type="agent" '
                 'args="robot1 \'unbalanced"/>\n</launch>\n')
    assert_bad_input(run("launch", f, "--dry-run"), "q.launch:2", "no closing quotation")


def test_an_array_without_a_sibling_size_is_invalid(tmp_path):
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(textwrap.dedent("""\
        <rqt_mrta><architecture><name>A</name>
          <robots><type>ST</type></robots><tasks><type>SR</type></tasks>
          <allocations><type>IA</type></allocations></architecture>
          <configs><config_0><id>c</id>
            <params_0><name>sensors</name>
              <array_0><name>sensor@index@</name>
                <param_0><name>topic</name></param_0></array_0>
            </params_0>
          </config_0></configs>
        </rqt_mrta>
        """))
    assert_bad_input(run("arch", "validate", f), "rqt_mrta.xml:6", "sibling <param> named 'size'")
