"""rqt_mrta files: the reference files load and round-trip; malformed ones are told where and why."""

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from tests.harness.helpers import ALLIANCE_ARCH, ROOT
from mrta_zenoh.toolchain.model import ApplicationFile, ArchitectureFile, Array, Param, Params
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta, to_xml
from tests.harness.helpers import REFERENCE

# every rqt_mrta file the original project ships (alliance_test's package.xml exports an
# application file it never shipped: test_toolchain_apps checks the registry says so)
REFERENCE_FILES = ["alliance/rqt_mrta.xml", "dissertation_examples/a_arch_config-rqt_mrta.xml",
                   "dissertation_examples/b_app_config-rqt_mrta.xml"]


@pytest.mark.parametrize("rel", REFERENCE_FILES)
def test_reference_file_loads_and_round_trips(reference, tmp_path, rel):
    path = REFERENCE / rel
    model = load_rqt_mrta(path)
    out = tmp_path / "again.xml"
    out.write_bytes(to_xml(model))
    assert load_rqt_mrta(out) == model


def test_reference_models_hold_what_the_files_say(reference):
    arch = load_rqt_mrta(REFERENCE / "alliance/rqt_mrta.xml")
    assert isinstance(arch, ArchitectureFile) and arch.taxonomy == "ST-SR-IA"
    assert arch.busy_robots.field == "header/frame_id" and arch.allocated_tasks.timeout == 0.5
    robot = arch.config("alliance_params")
    sensors = next(c for c in robot.children if c.name == "sensors")
    assert isinstance(sensors, Params) and isinstance(sensors.children[1], Array)
    assert sensors.children[0].value == "@array_size@"
    app = load_rqt_mrta(REFERENCE / "dissertation_examples/b_app_config-rqt_mrta.xml")
    assert isinstance(app, ApplicationFile) and app.name == "Patrulha na UNIFEI"
    # ids normalised where the file is read (one key chunk everywhere after), written back as
    # the file wrote them
    assert [r.id for r in app.robots] == ["robot1", "robot2", "robot3"]
    assert [r.written for r in app.robots] == ["/robot1", "/robot2", "/robot3"]
    assert b"<id>/robot1</id>" in to_xml(app)
    assert app.tasks() == ["wander", "border_protection", "report"]
    assert len(app.configs) == 5 and len(app.launches) == 3


def test_our_architecture_round_trips_and_uses_zenoh_keys(tmp_path):
    arch = load_rqt_mrta(ALLIANCE_ARCH / "rqt_mrta.xml")
    assert arch.busy_robots.name == "*/alliance/inter_robot_communication"
    (tmp_path / "a.xml").write_bytes(to_xml(arch))
    assert load_rqt_mrta(tmp_path / "a.xml") == arch
    mandatory = [c for c in arch.config("alliance_params").children
                 if isinstance(c, Param) and c.mandatory]
    assert [p.name for p in mandatory] == ["name"]


ARCH = """<?xml version="1.0"?>
<rqt_mrta>
  <architecture>
    <name>X</name>
    <robots><type>ST</type>{robots}</robots>
    <tasks><type>SR</type></tasks>
    <allocations><type>IA</type></allocations>
  </architecture>
  <configs>
    <config_0>
      <id>c</id>
      {param}
    </config_0>
  </configs>
</rqt_mrta>
"""
OK_PARAM = "<param_0><name>p</name><type>double</type></param_0>"

MALFORMED = [
    (ARCH.format(robots="<busy_robot/>", param=OK_PARAM), 5, "did you mean 'busy_robots'"),
    (ARCH.format(robots="", param="<param_0><name>p</name><type>float</type></param_0>"), 12,
     "must be one of bool|int|double|string"),
    (ARCH.format(robots="", param="<param_0><name>p</name><type>int</type><default>x</default>"
                              "</param_0>"), 12, "expected an int"),
    (ARCH.format(robots="<busy_robots><topic><name>k</name><type>t</type><field>f</field>"
                        "<timeout>-1</timeout></topic></busy_robots>", param=OK_PARAM), 5,
     "<timeout> must be between 0.001 and 86400 s"),
    # finite but absurd: `mrta supervise --once` never returned
    (ARCH.format(robots="<busy_robots><topic><name>k</name><type>t</type><field>f</field>"
                        "<timeout>1e308</timeout></topic></busy_robots>", param=OK_PARAM), 5,
     "(a millisecond to a day), got 1e+308"),
    (ARCH.format(robots="<busy_robots><topic><name>k</name><type>t</type><field>f</field>"
                        "<queue_size>1000000000</queue_size></topic></busy_robots>",
                 param=OK_PARAM), 5, "<queue_size> must be between 1 and 100000 samples"),
    # what the supervisor refuses when it subscribes, refused at load with its line
    (ARCH.format(robots="<busy_robots><topic><name>a//b</name><type>t</type><field>f</field>"
                        "</topic></busy_robots>", param=OK_PARAM), 5, "has an empty chunk"),
    (ARCH.format(robots="<busy_robots><topic><name>a/b*/c</name><type>t</type><field>f</field>"
                        "</topic></busy_robots>", param=OK_PARAM), 5, "'*' must be a whole chunk"),
    (ARCH.format(robots="<busy_robots><topic><name>k</name><type>t</type>"
                        "<field>header//frame_id</field></topic></busy_robots>", param=OK_PARAM),
     5, "has an empty part"),
    (ARCH.format(robots="<busy_robots><topic><name>k</name><type>t</type>"
                        "<field>header/frame-id</field></topic></busy_robots>", param=OK_PARAM),
     5, "neither a field name nor an index"),
    (ARCH.format(robots="<config_id>nope</config_id>", param=OK_PARAM), 5, "no config has id"),
    (ARCH.format(robots="", param="<parm_0><name>p</name></parm_0>"), 12, "did you mean"),
    (ARCH.format(robots="", param="<param_0><type>int</type></param_0>"), 12, "needs a <name>"),
    (ARCH.replace("<type>SR</type>", "<type>XR</type>").format(robots="", param=OK_PARAM), 6,
     "must be one of SR, MR"),
    ("<rqt_mrta><architecture>", 1, "not well-formed"),
    ("<rqtmrta/>", 1, "root element must be <rqt_mrta>"),
]


@pytest.mark.parametrize("text,line,message", MALFORMED, ids=[m[2] for m in MALFORMED])
def test_malformed_architecture_names_file_line_and_element(tmp_path, text, line, message):
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_rqt_mrta(f)
    assert message in str(err.value)
    assert err.value.file == str(f) and err.value.line == line, str(err.value)
    res = CliRunner().invoke(cli, ["arch", "validate", str(f)])
    assert res.exit_code == 2 and f"{f}:{line}" in res.output


def test_validate_accepts_good_files_and_refuses_the_wrong_kind(reference):
    r = CliRunner()
    assert r.invoke(cli, ["arch", "validate", str(REFERENCE / "alliance/rqt_mrta.xml")]).exit_code == 0
    app = str(REFERENCE / "dissertation_examples/b_app_config-rqt_mrta.xml")
    assert r.invoke(cli, ["app", "validate", app]).exit_code == 0
    res = r.invoke(cli, ["arch", "validate", app])
    assert res.exit_code == 2 and "not an architecture file" in res.output


APP = """<?xml version="1.0"?>
<rqt_mrta>
  <application>
    <architecture>alliance</architecture>
    <name>A</name>
    <robots>
      <robot_0><id>robot1</id><tasks><task_0><id>wander</id></task_0></tasks></robot_0>
      <robot_1><id>{second}</id><tasks><task_0><id>{task}</id></task_0></tasks></robot_1>
    </robots>
  </application>
</rqt_mrta>
"""

BAD_APPS = [
    (APP.format(second="robot1", task="wander"), 8, "robot 'robot1' appears twice (first on line 7)"),
    (APP.format(second="/robot1", task="wander"), 8, "robot 'robot1' appears twice"),
    (APP.format(second="robot 2", task="wander"), 8, "invalid robot id 'robot 2'"),
    (APP.format(second="robot2/x", task="wander"), 8, "invalid robot id"),
    (APP.format(second="robot2", task="wan*der"), 8, "invalid task id 'wan*der'"),
]


@pytest.mark.parametrize("text,line,message", BAD_APPS, ids=[m[2][:30] for m in BAD_APPS])
def test_app_validate_refuses_what_the_runtime_refuses_with_its_line(tmp_path, text, line,
                                                                       message):
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(text)
    res = CliRunner().invoke(cli, ["app", "validate", str(f)])
    assert res.exit_code == 2 and f"{f}:{line}" in res.output and message in res.output, res.output
    # and the runtime refuses it the same way, for it reads the file through the same reader
    from mrta_supervisor.live.api import resolve_application

    with pytest.raises(ConfigError) as err:
        resolve_application(str(f))
    assert err.value.line == line and message in str(err.value)


def test_a_good_application_still_validates(tmp_path):
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(APP.format(second="/robot2", task="wander"))
    res = CliRunner().invoke(cli, ["app", "validate", str(f)])
    assert res.exit_code == 0, res.output


@pytest.mark.slow
def test_app_validate_reads_every_robots_files_as_its_agent_would(tmp_path):
    """An application must not validate and then have every agent refuse its files at launch:
    `mrta app validate` runs the architecture's own check (Architecture.check_files)."""
    import shutil

    from click.testing import CliRunner

    from mrta_zenoh.cli.main import cli
    pkg = tmp_path / "patrol"
    shutil.copytree(ROOT / "configs" / "applications" / "patrol", pkg,
                    ignore=shutil.ignore_patterns("__pycache__"))
    good = CliRunner().invoke(cli, ["app", "validate", str(pkg)])
    assert good.exit_code == 0 and "the parameter files of 3 robots checked" in good.output
    f = pkg / "config" / "robot2_alliance_params.yaml"
    f.write_text(f.read_text().replace("timeout_duration: 3.0", "timeout_duration: 1.0e+308", 1))
    bad = CliRunner().invoke(cli, ["app", "validate", str(pkg)])
    assert bad.exit_code == 2
    assert "robot2_alliance_params.yaml:" in bad.output and "between 0.001 and 86400 s" in bad.output


def test_an_unknown_architecture_is_named_with_file_and_line(tmp_path):
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(APP.format(second="robot2", task="wander").replace(
        "<architecture>alliance</architecture>", "<architecture>aliance</architecture>"))
    res = CliRunner().invoke(cli, ["app", "validate", str(f)])
    assert res.exit_code == 2, res.output
    (line,) = res.output.strip().splitlines()
    assert line.startswith(f"Error: {f}:4: <architecture>: unknown architecture 'aliance' "
                           "(did you mean 'alliance'?) (known: "), line


@pytest.mark.parametrize("data,line,what", [
    (b"<rqt_mrta>\n<a>\x00</a></rqt_mrta>", 2, "Char 0x0 out of allowed range"),
    (b"<rqt_mrta>" + b"<a>" * 5000 + b"</a>" * 5000 + b"</rqt_mrta>", 1, "Excessive depth"),
    (b"<rqt_mrta>\n<a>caf\xe9</a></rqt_mrta>", None, "Invalid bytes in character encoding"),
])
def test_hostile_xml_is_one_line_naming_the_file(tmp_path, data, line, what):
    f = tmp_path / "rqt_mrta.xml"
    f.write_bytes(data)
    res = CliRunner().invoke(cli, ["arch", "validate", str(f)])
    assert res.exit_code == 2, res.output
    (out,) = res.output.strip().splitlines()
    assert out.startswith(f"Error: {f}:{line}: " if line else f"Error: {f}: ") and what in out


def test_a_file_read_again_is_a_copy_of_the_first_reading_until_its_bytes_change(tmp_path):
    """load_rqt_mrta keeps what it read per path and content (a process reads its application
    and architecture again and again): a caller that changes its model changes its own copy,
    and a file rewritten — even to the same size, within one tick of the file clock — is read
    again."""
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(APP.format(second="robot2", task="wander"))
    first = load_rqt_mrta(f)
    first.robots[1].tasks.append("changed by its caller")
    again = load_rqt_mrta(f)
    assert again is not first and [r.tasks for r in again.robots] == [["wander"], ["wander"]]
    f.write_text(APP.format(second="robot3", task="wander"))  # the same size
    assert [r.id for r in load_rqt_mrta(f).robots] == ["robot1", "robot3"]


def test_an_applications_architecture_is_read_without_reading_the_rest(tmp_path, reference):
    """A run under another architecture sets the application's own package aside after reading
    its file only as far as <architecture> (a derived 100-robot one is ≈ 24 MB: issue 47)."""
    from mrta_zenoh.toolchain.xmlio import application_architecture
    f = tmp_path / "rqt_mrta.xml"
    f.write_text("<rqt_mrta>\n  <application>\n    <architecture> cbba </architecture>\n"
                 "    <name>x</name>\n  <broken")  # not well-formed after it: never reached
    assert application_architecture(f) == "cbba"
    with pytest.raises(ConfigError):
        load_rqt_mrta(f)
    f.write_text("<rqt_mrta><architecture><architecture>x</architecture></architecture>"
                 "</rqt_mrta>")
    assert application_architecture(f) is None  # an architecture file: read it whole
    f.write_text("<rqt_mrta><application><name>x</")
    assert application_architecture(f) is None  # broken before it: read it whole, for why
    assert application_architecture(tmp_path / "none.xml") is None
