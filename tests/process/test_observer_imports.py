"""A run's observers load no library they do not use: the mission runner, the recorder and the
simulator start once per run — a study starts them thousands of times — and matplotlib (≈ 1.5
CPU-s to import) or scipy.optimize (≈ 1 CPU-s) at their start were a quarter of a 5-robot hosted
run's CPU. They come in where a picture is drawn (`--no-plots` draws none) or a run is compared
with the optimum (the analysis, after the run). Checked in a fresh interpreter, where
`sys.modules` tells the truth."""

import subprocess
import sys

import pytest

pytestmark = pytest.mark.multiprocess

PROBE = """
import sys
import mrta_supervisor.mission.runner, mrta_supervisor.mission.cli
import mrta_supervisor.live.cli, mrta_supervisor.live.viewer
import simulator.cli
from mrta_supervisor.mission.hook import missions
for entry in missions().values():  # the runner and the recorder load the application's hook
    entry.load()
print(",".join(sorted(set(sys.modules) & set(sys.argv[1:]))))
"""


def test_the_observers_start_without_plotting_or_optimisation_libraries():
    out = subprocess.run([sys.executable, "-c", PROBE, "matplotlib", "scipy.optimize"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == ""
