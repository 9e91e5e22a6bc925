"""Registry, the new-application wizard (prompts and answers file) and launch files."""

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import ALLIANCE_ARCH, CONFIGS
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta
from mrta_agent.alliance.params import load_agent_params
from tests.harness.helpers import REFERENCE

PATROL_ANSWERS = CONFIGS / "applications" / "patrol_answers.yaml"

WIZARD_KEYS = [
    "mypkg", "My App", "", "", "Ana", "not-an-email", "ana@example.org",
    "", "", "",                                     # licence, mission, dependencies
    "single-task", "", "", "",                      # filters (robots: ST only), then arch 1
    "robot1,robot2", "wander,report", "wander", "",  # robot1 does wander, robot2 both
    # robot1_alliance_params
    "Robot 1", "", "", "", "", "1", "mrta/odometry", "odom", "", "",
    "abc", "60", "20", "30", "60", "2", "", "1", "odom",   # 'abc' is refused: double expected
    # robot2_alliance_params
    "Robot 2", "", "", "", "", "1", "mrta/point_cloud", "sonar", "", "",
    "60", "20", "30", "60", "2", "", "1", "sonar",
    "90", "25", "40", "80", "1", "", "1", "sonar",
    # tasks_alliance_params
    "2", "wander", "Wander", "1", "patrol/wander", "report", "Report", "1", "patrol/report",
    # layers_alliance_params: keep every default (one Enter per parameter of the template)
    *[""] * sum(len(group.children) for group in load_rqt_mrta(
        ALLIANCE_ARCH / "rqt_mrta.xml").config("layers_alliance_params").children),
    "y",
]


def run(*args, env=None, input=None):
    return CliRunner().invoke(cli, list(args), env=env, input=input)


@pytest.mark.slow
def test_wizard_with_scripted_keystrokes_writes_a_package_the_tools_accept(tmp_path):
    res = run("app", "new", "--output", str(tmp_path), input="\n".join(WIZARD_KEYS) + "\n")
    assert res.exit_code == 0, res.output
    assert "not a valid e-mail address" in res.output and "expected a double" in res.output
    assert "5/5 Summary" in res.output and "config/robot2_alliance_params.yaml" in res.output
    pkg = tmp_path / "mypkg"
    check_generated_package(pkg, {"robot1": ["wander"], "robot2": ["wander", "report"]})


@pytest.mark.slow
def test_answers_file_writes_the_same_package_without_prompts(tmp_path):
    res = run("app", "new", "--answers", str(PATROL_ANSWERS), "--output", str(tmp_path))
    assert res.exit_code == 0, res.output
    tasks = ["wander", "border_protection", "report"]
    check_generated_package(tmp_path / "patrol", {r: tasks for r in ("robot1", "robot2", "robot3")})
    # and the shipped patrol application is exactly what the answers produce
    for f in sorted((tmp_path / "patrol").rglob("*")):
        if f.is_file():
            rel = f.relative_to(tmp_path / "patrol")
            shipped = CONFIGS / "applications" / "patrol" / rel
            assert shipped.read_bytes() == f.read_bytes(), f"{rel} differs from the answers"


def check_generated_package(pkg: Path, robots: dict):
    env = {"MRTA_PACKAGE_PATH": str(pkg.parent)}
    listed = run("app", "list", "--json", env=env)
    assert f'"path": "{pkg}"' in listed.output
    assert run("app", "validate", str(pkg / "rqt_mrta.xml")).exit_code == 0
    for rid, tasks in robots.items():
        params = load_agent_params(pkg / "config" / f"{rid}_alliance_params.yaml",
                                   pkg / "config" / "tasks_alliance_params.yaml",
                                   pkg / "config" / "layers_alliance_params.yaml")
        assert [b.task_id for b in params.robot.behaviour_sets] == tasks
    dry = run("launch", pkg.name, f"{pkg.name}.launch", "--dry-run", env=env)
    assert dry.exit_code == 0, dry.output
    lines = [x for x in dry.output.splitlines() if "robot_agent/agent" in x]
    assert len(lines) == len(robots)
    for rid in robots:
        assert any(f"robot_agent/agent {rid} --robot-params {pkg}/config/{rid}_alliance_params.yaml"
                   in x for x in lines)


@pytest.mark.slow
def test_existing_folder_is_kept_without_force_and_replaced_with_it(tmp_path):
    (tmp_path / "patrol").mkdir()
    (tmp_path / "patrol" / "mine.txt").write_text("keep me")
    res = run("app", "new", "--answers", str(PATROL_ANSWERS), "--output", str(tmp_path))
    assert res.exit_code == 2 and "already exists; use --force" in res.output
    assert (tmp_path / "patrol" / "mine.txt").read_text() == "keep me"
    res = run("app", "new", "--answers", str(PATROL_ANSWERS), "--output", str(tmp_path), "--force")
    assert res.exit_code == 0 and not (tmp_path / "patrol" / "mine.txt").exists()


def answers_with(**changes) -> str:
    data = yaml.safe_load(PATROL_ANSWERS.read_text())
    for path, value in changes.items():
        node = data
        keys = path.split("__")
        for k in keys[:-1]:
            node = node[int(k) if k.isdigit() else k]
        if value is None:
            del node[keys[-1]]
        else:
            node[int(keys[-1]) if keys[-1].isdigit() else keys[-1]] = value
    return yaml.safe_dump(data, sort_keys=False)


BAD_ANSWERS = [
    ({"email": "ana(at)example"}, "not a valid e-mail address"),
    ({"package": "My-Package"}, "use lower-case letters"),
    ({"version": "1.0"}, "expected MAJOR.MINOR.PATCH"),
    ({"architecture": "aliance"}, "unknown architecture 'aliance' (did you mean 'alliance'?)"),
    ({"configs__alliance_params__robot1__name": None}, "mandatory parameter missing"),
    ({"configs__alliance_params__robot1__spin_rate": "fast"}, "expected a double"),
    ({"configs__alliance_params__robot1__spin_rat": 2}, "unknown parameter (did you mean 'spin_rate'?)"),
    ({"configs__layer_params": {}}, "did you mean 'layers_alliance_params'"),
    ({"robots__robot1": []}, "give at least one task"),
    ({"configs__alliance_params__robot1__behaviour_sets": [{}]}, "one entry per task"),
    ({"maintainerr": "x"}, "did you mean 'maintainer'"),
]


@pytest.mark.slow
@pytest.mark.parametrize("changes,message", BAD_ANSWERS, ids=[b[1] for b in BAD_ANSWERS])
def test_bad_answers_exit_2_with_the_message_and_write_nothing(tmp_path, changes, message):
    f = tmp_path / "answers.yaml"
    f.write_text(answers_with(**changes))
    out = tmp_path / "out"
    res = run("app", "new", "--answers", str(f), "--output", str(out))
    assert res.exit_code == 2, res.output
    assert message in res.output
    assert not out.exists() or not any(out.iterdir())


def test_taxonomy_filter_and_aliases():
    assert "ALLIANCE" in run("arch", "list", "--robots", "single-task", "--tasks", "SR").output
    assert "ALLIANCE" in run("arch", "list", "--allocations", "Instantaneous Assignment").output
    assert "ALLIANCE" not in run("arch", "list", "--robots", "MT").output
    res = run("arch", "list", "--tasks", "ST")
    assert res.exit_code == 2 and "expected one of SR, MR" in res.output


def test_registry_on_mrta_package_path_shadows_and_reports(reference):
    env = {"MRTA_PACKAGE_PATH": str(REFERENCE)}
    res = run("arch", "list", "--json", env=env)
    assert '"origin": "MRTA_PACKAGE_PATH' in res.output  # the reference alliance wins
    assert "is shadowed by" in res.output  # ours in configs/ is reported, not silently dropped
    shown = run("arch", "show", "ALLIANCE", env=env)
    assert "/alliance/inter_robot_communication (alliance_msgs" in shown.output
    # alliance_test exports an application file that is not there: said, not crashed
    res = run("app", "list", env=env)
    assert res.exit_code == 0 and "alliance_test/rqt_mrta.xml does not exist" in res.output


@pytest.mark.slow
@pytest.mark.multiprocess
def test_an_installed_distribution_adds_an_architecture_through_its_entry_point(tmp_path):
    site = tmp_path / "site"
    pkg = site / "thirdparty_arch"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "package.xml").write_text(textwrap.dedent("""\
        <package><name>thirdparty_arch</name><version>0.1.0</version>
          <export><rqt_mrta architecture="${prefix}/rqt_mrta.xml"/></export></package>"""))
    (pkg / "rqt_mrta.xml").write_text(textwrap.dedent("""\
        <rqt_mrta><architecture><name>Auctioneer</name>
          <robots><type>MT</type></robots><tasks><type>MR</type></tasks>
          <allocations><type>TA</type></allocations></architecture></rqt_mrta>"""))
    dist = site / "thirdparty_arch-0.1.0.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: thirdparty-arch\nVersion: 0.1.0\n")
    (dist / "entry_points.txt").write_text("[mrta.packages]\nthirdparty_arch = thirdparty_arch\n")
    env = dict(os.environ, PYTHONPATH=str(site), MRTA_PACKAGE_PATH="")
    out = subprocess.run([sys.executable, "-m", "mrta_zenoh.cli.main", "arch", "list",
                          "--robots", "MT"], env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "thirdparty_arch" in out.stdout and "MT-MR-TA" in out.stdout
    assert "entry point thirdparty_arch (thirdparty-arch)" in out.stdout


def test_an_application_named_by_its_package_is_read_alone(monkeypatch):
    """A run's observers look their application up by package name: only that package's file is
    read (a derived 100-robot package's rqt_mrta.xml is ≈ 11 MB, 1.6 CPU-s to read, and an
    instance derives five), and a run's architecture reads the dependents until one runs it."""
    import mrta_zenoh.toolchain.registry as registry
    from mrta_supervisor.mission.hook import MissionOptions, resolve

    Registry = registry.Registry
    read = []
    real = registry.load_rqt_mrta
    monkeypatch.setattr(registry, "load_rqt_mrta", lambda f: read.append(f) or real(f))
    reg = Registry()
    pkg, app = reg.application("delivery_cbba")
    assert pkg.name == "delivery_cbba" and app.architecture == "cbba"
    assert read == [pkg.application_file]
    read.clear()
    run = resolve(MissionOptions(application="delivery", architecture="cbba"), reg)
    applications = [f for f in read if f.parent.name.startswith("delivery")]
    assert run.package.name == "delivery_cbba"
    assert len(applications) < len([p for p in reg.packages.values() if p.application_file])
