"""An experiment's runs forked by its fork server (the default: mrta_zenoh.forkserver) give the
rows of runs started as fresh interpreters (`--no-fork-server`) but for the machine's columns
(results.MACHINE_TIME): the server changes the CPU a run costs, never what it measures. (The
study's own proof, on file 01's committed rows, is in docs/study/README.md, "Cost".)"""

from __future__ import annotations

import csv
import pytest

from mrta_supervisor.experiment.results import MACHINE_TIME


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_forked_runs_give_the_rows_of_fresh_ones(children, tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: delivery\nduration: 10\nseeds: [1, 2]\n"
                 "failures: [robot3@5]\n")
    rows, said = {}, {}
    for flag in ("--fork-server", "--no-fork-server"):
        out = tmp_path / flag.strip("-")
        run = children.mrta("experiment", "run", f, "--output", out, "--jobs", "1",
                            "--no-plots", flag, name=f"experiment {flag}")
        assert run.wait(500) == 0, run.stderr[-10:]
        rows[flag] = [{k: v for k, v in r.items() if k not in MACHINE_TIME}
                      for r in csv.DictReader((out / "results.csv").open())]
        said[flag] = [line for line in run.stderr if "fork server forked" in line]
    assert rows["--fork-server"] == rows["--no-fork-server"]
    assert [r["status"] for r in rows["--fork-server"]] == ["ok", "ok"]
    # each run's runner, recorder, simulator and agents were forked, not started fresh
    assert len(said["--fork-server"]) == 1 and int(said["--fork-server"][0].split()[-2]) >= 8
    assert said["--no-fork-server"] == []

