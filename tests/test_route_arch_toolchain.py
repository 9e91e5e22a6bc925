"""SSI and CBBA through the toolchain: registered by entry point and listed by `mrta arch list`
(a TA architecture each), their delivery applications generated from the answers files beside
the others (exactly the shipped files but the hand-written ones), each robot file naming the
instance its decision logic plans on. That every architecture validates and its packages are
what their answers write, byte for byte: tests/test_conformance.py."""

import json

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import CONFIGS

HAND_WRITTEN = {"__init__.py", "config/layers_{a}_params.yaml", "config/instance.yaml",
                "launch/delivery_sim.launch"}


def run(*args):
    return CliRunner().invoke(cli, list(args))


def test_arch_list_lists_ssi_and_cbba_as_task_allocation():
    out = run("arch", "list", "--allocations", "TA", "--json").output
    found = {json.loads(line)["name"]: json.loads(line) for line in out.splitlines()}
    assert {"ssi", "cbba"} <= set(found)
    assert found["ssi"]["taxonomy"] == found["cbba"]["taxonomy"] == "ST-SR-TA"
    # `mrta arch validate`: the conformance suite's, for every architecture


@pytest.mark.parametrize("arch", ["ssi", "cbba"])
def test_the_answers_generate_the_shipped_application_but_its_hand_written_files(tmp_path, arch):
    from importlib import import_module
    load_params = import_module(f"mrta_agent.{arch}.params").load_params
    package = f"delivery_{arch}"
    shipped = CONFIGS / "applications" / package
    res = run("app", "new", "--answers", str(CONFIGS / "applications" / f"{package}_answers.yaml"),
              "--output", str(tmp_path))
    assert res.exit_code == 0, res.output
    pkg = tmp_path / package
    generated = {str(f.relative_to(pkg)) for f in pkg.rglob("*") if f.is_file()}
    on_disk = {str(f.relative_to(shipped)) for f in shipped.rglob("*")
               if f.is_file() and "__pycache__" not in f.parts}
    assert on_disk == generated | {h.format(a=arch) for h in HAND_WRITTEN}
    # byte for byte and `mrta app validate`: the conformance suite's, for every architecture
    params = load_params("robot3", shipped / "config" / f"robot3_{arch}_params.yaml",
                         shipped / "config" / f"tasks_{arch}_params.yaml")
    assert [r.id for r in params.problem.robots] == [f"robot{k}" for k in range(1, 6)]


def test_a_bad_robot_file_names_file_line_and_key(tmp_path):
    from mrta_agent.ssi.architecture import SSI
    from mrta_agent.runtime.host import AgentOptions
    from mrta_zenoh.errors import ConfigError
    config = CONFIGS / "applications" / "delivery_ssi" / "config"
    text = (config / "robot1_ssi_params.yaml").read_text()
    bad = tmp_path / "robot1_ssi_params.yaml"
    bad.write_text(text.replace("join_wait:", "join_wiat:"))
    with pytest.raises(ConfigError, match=r"robot1_ssi_params.yaml:\d+: 'join_wiat'.*join_wait"):
        SSI.prepare(AgentOptions("robot1", bad, config / "tasks_ssi_params.yaml"))
    bad.write_text(text)  # beside it, no instance.yaml
    with pytest.raises(ConfigError, match="instance file .*instance.yaml does not exist"):
        SSI.prepare(AgentOptions("robot1", bad, config / "tasks_ssi_params.yaml"))
    SSI.check_files("robot1", bad, config / "tasks_ssi_params.yaml")  # the files alone are fine
