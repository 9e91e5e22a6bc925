"""MURDOCH through the same toolchain as ALLIANCE: registered by entry point, listed by the
taxonomy filter, its patrol application generated from an answers file and accepted by
`mrta app validate`, its launch files resolved to `mrta murdoch` processes."""

import json
import pytest

from click.testing import CliRunner

from mrta_agent.murdoch.params import load_params
from mrta_zenoh.cli.main import cli
from tests.harness.helpers import CONFIGS

ANSWERS = CONFIGS / "applications" / "patrol_murdoch_answers.yaml"
SHIPPED = CONFIGS / "applications" / "patrol_murdoch"
HAND_WRITTEN = {"__init__.py"}  # the rest, launch/patrol_sim.launch too, from the answers


def run(*args, env=None):
    return CliRunner().invoke(cli, list(args), env=env)


def test_arch_list_by_taxonomy_lists_both_architectures():
    out = run("arch", "list", "--allocations", "IA", "--json").output
    found = {json.loads(line)["name"]: json.loads(line) for line in out.splitlines()}
    assert {"ALLIANCE", "MURDOCH"} <= set(found)
    assert found["MURDOCH"]["taxonomy"] == "ST-SR-IA"
    assert "MURDOCH" not in run("arch", "list", "--allocations", "TA").output
    assert run("arch", "validate", "murdoch").exit_code == 0


@pytest.mark.slow
def test_the_answers_generate_the_shipped_application_which_validates(tmp_path):
    res = run("app", "new", "--answers", str(ANSWERS), "--output", str(tmp_path))
    assert res.exit_code == 0, res.output
    pkg = tmp_path / "patrol_murdoch"
    generated = {str(f.relative_to(pkg)) for f in pkg.rglob("*") if f.is_file()}
    shipped = {str(f.relative_to(SHIPPED)) for f in SHIPPED.rglob("*")
               if f.is_file() and "__pycache__" not in f.parts}
    assert shipped == generated | HAND_WRITTEN
    for rel in sorted(generated):
        assert (SHIPPED / rel).read_bytes() == (pkg / rel).read_bytes(), f"{rel} differs"
    res = run("app", "validate", str(pkg))
    assert res.exit_code == 0 and "valid application 'Patrol (MURDOCH)'" in res.output
    assert run("app", "validate", "patrol_murdoch").exit_code == 0
    for rid in ("robot1", "robot2", "robot3"):
        params = load_params(pkg / "config" / f"{rid}_murdoch_params.yaml",
                             pkg / "config" / "tasks_murdoch_params.yaml")
        assert [s.task_id for s in params.robot.skills] == ["wander", "border_protection", "report"]
    assert params.tasks["report"].locations == ((-12.0, 4.5),)


def test_an_application_naming_an_unregistered_architecture_is_refused(tmp_path):
    text = (SHIPPED / "rqt_mrta.xml").read_text().replace(
        "<architecture>murdoch</architecture>", "<architecture>murdok</architecture>")
    (tmp_path / "rqt_mrta.xml").write_text(text)
    res = run("app", "validate", str(tmp_path / "rqt_mrta.xml"))
    assert res.exit_code == 2 and "murdok" in res.output and "murdoch" in res.output


def test_the_launch_file_starts_one_murdoch_agent_per_robot():
    res = run("launch", "patrol_murdoch", "patrol_sim.launch", "--dry-run")
    assert res.exit_code == 0, res.output
    agents = [x for x in res.output.splitlines() if "murdoch/agent" in x]
    assert len(agents) == 3
    for rid in ("robot1", "robot2", "robot3"):
        assert any(f"murdoch/agent {rid} --robot-params {SHIPPED}/config/{rid}_murdoch_params.yaml"
                   in x and "--sim-time" in x for x in agents)


def test_mrta_murdoch_exits_2_on_a_bad_parameter_file_before_opening_a_bus(tmp_path):
    bad = tmp_path / "robot1_murdoch_params.yaml"
    bad.write_text((SHIPPED / "config" / "robot1_murdoch_params.yaml").read_text()
                   .replace("lease_timeout: 2.0", "lease_timeout: 0.2"))
    res = run("murdoch", "robot1", "--robot-params", str(bad),
              "--tasks-params", str(SHIPPED / "config" / "tasks_murdoch_params.yaml"))
    assert res.exit_code == 2
    assert f"{bad}:" in res.output and "lease_timeout" in res.output
