"""`mrta app new` makes an application `mrta demo` runs (issue 51, the newcomer's list: it wrote
no simulation launch file, so a new application could not run there): given a mission, the
package gets that mission's launch file with its own robots and agents, and the mission's
layers file where its architecture has no template for one (mrta_zenoh/toolchain/
missionfiles.py). The run itself: tests/process/test_wizard_demo.py; the shipped package made
so, byte for byte: tests/test_murdoch_toolchain.py."""

from __future__ import annotations

import pytest
import yaml
from click.testing import CliRunner
from lxml import etree

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import CONFIGS

MURDOCH_ANSWERS = CONFIGS / "applications" / "patrol_murdoch_answers.yaml"


def answers(tmp_path, **change):
    data = yaml.safe_load(MURDOCH_ANSWERS.read_text())
    data.update(package="my_patrol", depends=[])
    robots = data["configs"]["murdoch_params"]
    data["robots"] = {"alpha": data["robots"]["robot1"], "robot2": data["robots"]["robot2"]}
    data["configs"]["murdoch_params"] = {"alpha": robots["robot1"], "robot2": robots["robot2"]}
    data.update(change)
    f = tmp_path / "answers.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False))
    return f


def make(tmp_path, **change):
    return CliRunner().invoke(cli, ["app", "new", "--answers", str(answers(tmp_path, **change)),
                                    "--output", str(tmp_path / "apps")])


def test_a_package_made_for_the_patrol_mission_gets_its_launch_with_its_own_robots(tmp_path):
    res = make(tmp_path)
    assert res.exit_code == 0, res.output
    pkg = tmp_path / "apps" / "my_patrol"
    root = etree.parse(str(pkg / "launch" / "patrol_sim.launch")).getroot()
    (sim,) = root.iterfind("node")
    assert sim.get("required") == "true"
    # robot2 keeps the world's start of that name; alpha is placed by the world
    assert sim.get("args").split()[:5] == ["--world", "patrol", "--robot", "alpha", "--robot"]
    assert "--robot robot2 --speed" in sim.get("args") and "robot3" not in sim.get("args")
    (team,) = [e for e in root.iterfind("env") if e.get("name") == "MRTA_TEAM"]
    assert team.get("value") == "alpha,robot2"
    agents = {inc.find("arg[@name='robot_id']").get("value"):
              {a.get("name"): a.get("value") for a in inc.iterfind("arg")}
              for inc in root.iterfind("include")}
    assert list(agents) == ["alpha", "robot2"]
    assert agents["alpha"]["agent_args"] == "--sim-time"
    assert agents["alpha"]["robot_params"] == "$(find my_patrol)/config/alpha_murdoch_params.yaml"
    # MURDOCH has no layers template: patrol's layers, where the agents read theirs
    layers = yaml.safe_load((pkg / "config" / "layers_murdoch_params.yaml").read_text())
    assert layers["BorderProtection"]["x_max"] == 20.0 and set(layers) == {
        "Wander", "BorderProtection", "Report"}
    assert "<run_depend>patrol</run_depend>" in (pkg / "package.xml").read_text()
    assert f"MRTA_PACKAGE_PATH={tmp_path / 'apps'} mrta demo --application my_patrol" in res.output


def test_without_a_mission_nothing_is_derived_and_the_last_line_says_how(tmp_path):
    res = make(tmp_path, mission="")
    assert res.exit_code == 0, res.output
    assert not (tmp_path / "apps" / "my_patrol" / "launch" / "patrol_sim.launch").exists()
    assert "answer the wizard's mission question (delivery, patrol)" in res.output


@pytest.mark.parametrize("mission, said", [
    ("patrl", "mission 'patrl': no application registers it under mrta.missions; registered: "
              "delivery, patrol (did you mean 'patrol'?)"),
    ("delivery", "the delivery mission runs packages derived from an instance file, not made "
                 "here: mrta demo --application delivery --instance FILE --architecture ARCH"),
])
def test_a_mission_it_cannot_make_a_package_for_is_one_line_naming_the_line(tmp_path, mission,
                                                                             said):
    res = make(tmp_path, mission=mission)
    assert res.exit_code == 2, res.output
    (line,) = res.output.strip().splitlines()
    assert "answers.yaml:" in line and said in line, line
    assert not (tmp_path / "apps").exists()


CENTRAL_PATROL = {
    "architecture": "central", "robots": {"robot1": ["wander", "report"]},
    "configs": {"central_params": {"robot1": {"name": "Robot 1"}},
                "tasks_central_params": {"tasks": [
                    {"id": "wander", "name": "Wander", "layers": [{"plugin_name": "patrol/wander"}]},
                    {"id": "report", "name": "Report", "layers": [{"plugin_name": "patrol/report"}]}]},
                "dispatcher_central_params": {"objective": "minsum"}}}


def test_a_patrol_package_under_an_architecture_of_routes_is_refused_saying_why(tmp_path):
    """A patrol package for central was made, and ran its robots idle with no dispatcher
    (issue 51): patrol's tasks never end, and central's (SSI's, CBBA's) robots serve routes of
    tasks that do. Refused naming the line and the architectures that can."""
    res = make(tmp_path, **CENTRAL_PATROL)
    assert res.exit_code == 2, res.output
    (line,) = res.output.strip().splitlines()
    assert "answers.yaml:" in line and "'mission': the patrol mission's tasks are continuous" \
        in line and "run patrol under alliance or murdoch" in line, line
    assert not (tmp_path / "apps").exists()


@pytest.mark.parametrize("arch", ["central", "ssi", "cbba", "tessi"])
def test_the_demo_refuses_patrol_under_an_architecture_of_routes(arch):
    from mrta_supervisor.mission.hook import MissionOptions, resolve
    from mrta_zenoh.errors import ConfigError

    with pytest.raises(ConfigError, match="the patrol mission's tasks are continuous"):
        resolve(MissionOptions(application="patrol", architecture=arch))


def test_the_demo_refuses_a_patrol_package_made_for_central_before_the_refusal(tmp_path,
                                                                               monkeypatch):
    """A package an older wizard made (or one made by hand): refused by name, not run idle."""
    from mrta_supervisor.mission.hook import MissionOptions, resolve
    from mrta_zenoh.errors import ConfigError
    from mrta_zenoh.toolchain.registry import Registry

    assert make(tmp_path).exit_code == 0  # a MURDOCH package, then made central's by hand
    pkg = tmp_path / "apps" / "my_patrol"
    xml = pkg / "rqt_mrta.xml"
    xml.write_text(xml.read_text().replace("<architecture>murdoch</architecture>",
                                           "<architecture>central</architecture>"))
    monkeypatch.setenv("MRTA_PACKAGE_PATH", str(tmp_path / "apps"))
    with pytest.raises(ConfigError, match="my_patrol: the patrol mission's tasks are continuous"):
        resolve(MissionOptions(application="my_patrol"), Registry())


def test_the_wizard_asks_for_the_mission_and_says_what_it_takes():
    from mrta_zenoh.toolchain.wizard import InvalidAnswer, collect
    from mrta_zenoh.toolchain.registry import Registry

    said, asked = [], []

    class Script:
        answers = iter(["mypkg", "My app", "", "", "Me", "me@example.com", "", "delivery",
                        "patrol", "", "ST"])

        def step(self, title):
            pass

        section = say = step

        def ask(self, question, check, default=None, show_default=True):
            asked.append(question)
            if question.startswith("Filter by robots"):
                raise StopIteration  # far enough
            text = next(self.answers)
            try:
                return check(text if text or default is None else default)
            except InvalidAnswer as exc:
                said.append(str(exc))
                return self.ask(question, check, default, show_default)

    with pytest.raises(StopIteration):
        collect(Registry(), Script())
    assert "Mission it runs in `mrta demo` (delivery, patrol; empty for none)" in asked
    assert len(said) == 1 and said[0].startswith("the delivery mission runs packages derived")


def test_the_wizard_refuses_an_architecture_of_routes_for_patrol_and_asks_again():
    from mrta_zenoh.toolchain.registry import Registry
    from mrta_zenoh.toolchain.wizard import InvalidAnswer, collect

    said, picked = [], []

    class Script:
        answers = iter(["mypkg", "My app", "", "", "Me", "me@example.com", "", "patrol", "",
                        "", "", "", "central", "murdoch"])

        def step(self, title):
            pass

        section = say = step

        def ask(self, question, check, default=None, show_default=True):
            if question.startswith("Robot ids"):
                raise StopIteration  # far enough
            text = next(self.answers)
            try:
                out = check(text if text or default is None else default)
            except InvalidAnswer as exc:
                said.append(str(exc))
                return self.ask(question, check, default, show_default)
            if question == "Architecture":
                picked.append(out[0].name)
            return out

    with pytest.raises(StopIteration):
        collect(Registry(), Script())
    assert len(said) == 1 and said[0].startswith("the patrol mission's tasks are continuous")
    assert picked == ["murdoch"]
