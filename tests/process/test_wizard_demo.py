"""A new user's path, end to end with real processes (issue 51, the newcomer's list): an
application made by `mrta app new` for the patrol mission — MURDOCH, two robots named as the
patrol world has no start for — runs under `mrta demo` as the wizard's last line prints it,
found on MRTA_PACKAGE_PATH; before, the wizard wrote no simulation launch file and the demo
failed reading one. The one CI-tier process test of the feature (the derivation itself:
tests/test_wizard_mission.py)."""

from __future__ import annotations

import json
import shlex

import pytest
import yaml

from tests.harness.helpers import CONFIGS

pytestmark = pytest.mark.multiprocess


def two_robot_answers(tmp_path):
    data = yaml.safe_load((CONFIGS / "applications" / "patrol_murdoch_answers.yaml").read_text())
    data["package"] = "my_patrol"
    data["depends"] = []
    robots = data["configs"]["murdoch_params"]
    data["robots"] = {"alpha": data["robots"]["robot1"], "beta": data["robots"]["robot3"]}
    data["configs"]["murdoch_params"] = {"alpha": robots["robot1"], "beta": robots["robot3"]}
    f = tmp_path / "answers.yaml"
    f.write_text(yaml.safe_dump(data, sort_keys=False))
    return f


@pytest.mark.timeout(180)
def test_an_application_the_wizard_made_runs_under_the_demo_as_it_says(children, tmp_path):
    apps = tmp_path / "apps"
    made = children.mrta("app", "new", "--answers", two_robot_answers(tmp_path),
                         "--output", apps, name="app new")
    assert made.wait(60) == 0, made.stderr
    demo_line = next(x for x in made.stdout if " mrta demo " in x)
    argv = shlex.split(demo_line.split("#")[0])
    assert argv[0] == f"MRTA_PACKAGE_PATH={apps}" and argv[1:] == [
        "mrta", "demo", "--application", "my_patrol"]
    children.env["MRTA_PACKAGE_PATH"] = str(apps)
    out = tmp_path / "out"
    demo = children.mrta(*argv[2:], "--speed", "0", "--duration", "8", "--fail", "none",
                         "--no-plots", "--no-live", "--output", out, name="demo")
    assert demo.wait(150) == 0, "\n".join(demo.stderr[-20:])
    summary = json.loads((out / "summary.json").read_text())
    assert summary["application"] == "my_patrol" and summary["architecture"] == "murdoch"
    assert summary["robots"] == ["alpha", "beta"] and summary["run_status"] == "complete"
    # both agents ran the patrol's layers on the patrol world: each took a task
    assert all(summary["who_did_what"][r] for r in ("alpha", "beta")), summary["who_did_what"]
