"""One mission run, end to end, for any registered application and architecture: `mrta demo`
and every run of `mrta experiment`. It owns the hook an application subclasses and how a run is
resolved from it, its faults typed once (hook.py: `Mission`, `MissionOptions`, `MissionRun`,
re-exported here — applications import them from this package), the runner (runner.py: launch,
readiness and honest run status from run_watch.py, the live supervisor attached to the run,
faults named by role resolved in roles.py, parameter overrides in a package copy in
overrides.py) and the analysis of the recording (analysis.py) into summary.json (the one schema,
summary.py; who did what in simulated time, ground_truth.py; what the faults did,
fault_effects.py; the timeline plots, plots.py and `mrta plot`, plot_cli.py).
"""

from .hook import Mission, MissionOptions, MissionRun

__all__ = ["Mission", "MissionOptions", "MissionRun"]
