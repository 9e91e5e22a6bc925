"""Import names that cannot clash: our distribution installs only `mrta_*` top-level names, so
supervisord — the PyPI project `supervisor`, which owns that import name (a test extra) —
installs beside it and neither shadows the other. Checked in a fresh interpreter started from an
empty folder, so the repository's own folders (`supervisor/`, `simulator/`, `robot_agent/`) and
its `*.egg-info` are not on sys.path: only what is installed counts."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.harness.helpers import ROOT

pytestmark = pytest.mark.multiprocess

DIST = "mrta-zenoh"
# the repository's folder names: import names of other projects (supervisord) or too generic
FOLDERS = ("supervisor", "simulator", "robot_agent")

PROBE = f"""
import importlib.metadata as md, importlib.util, json
import supervisor.options            # supervisord's
import mrta_supervisor.live.state         # ours
ours = md.distribution({DIST!r})
top_level = (ours.read_text("top_level.txt") or "").split()
owners = md.packages_distributions()
print(json.dumps({{
    "supervisor": supervisor.options.__file__,
    "supervisor_dist": md.distribution("supervisor").locate_file("supervisor/options.py").__str__(),
    "mrta_supervisor": mrta_supervisor.live.state.__file__,
    "top_level": top_level,
    "owners": {{name: owners.get(name, []) for name in {FOLDERS!r}}},
    "specs": {{name: getattr(importlib.util.find_spec(name), "origin", None)
              for name in {FOLDERS!r}}},
}}))
"""


def clean_env() -> dict:
    env = dict(os.environ)
    env.pop("PYTHONPATH", None)  # nothing but the installed environment
    return env


@pytest.fixture(scope="module")
def probe(tmp_path_factory):
    empty = tmp_path_factory.mktemp("empty_cwd")
    out = subprocess.run([sys.executable, "-c", PROBE], cwd=empty, env=clean_env(),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout)


@pytest.mark.slow
def test_supervisord_and_our_supervisor_import_side_by_side(probe):
    assert Path(probe["supervisor"]) == Path(probe["supervisor_dist"])  # supervisord's file
    assert Path(probe["supervisor"]).parent != ROOT / "supervisor"
    assert Path(probe["mrta_supervisor"]).name == "state.py"


@pytest.mark.slow
def test_our_distribution_provides_only_mrta_import_names(probe):
    assert probe["top_level"], "no top_level.txt in the installed mrta-zenoh"
    assert all(name.startswith("mrta_") for name in probe["top_level"]), probe["top_level"]
    for name in FOLDERS:
        assert DIST not in probe["owners"][name], (name, probe["owners"][name])
    assert probe["owners"]["supervisor"] == ["supervisor"]


@pytest.mark.slow
def test_the_repository_folder_names_are_not_importable_from_elsewhere(probe):
    specs = probe["specs"]
    assert specs["simulator"] is None and specs["robot_agent"] is None, specs
    # `supervisor` is supervisord's package, not our folder
    assert Path(specs["supervisor"]).parent == Path(probe["supervisor_dist"]).parent, specs


def test_mrta_help_runs_from_an_empty_folder(tmp_path):
    mrta = Path(sys.executable).with_name("mrta")
    assert mrta.is_file(), f"{mrta}: the console script is not installed"
    out = subprocess.run([str(mrta), "--help"], cwd=tmp_path, env=clean_env(),
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    assert "Usage:" in out.stdout and "supervise" in out.stdout, out.stdout
