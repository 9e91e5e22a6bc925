"""`--fork-server` reaches every backend (issue 48): the local one forks an experiment's runs
from one server; a SLURM array task and a Dask task fork their run's processes from a server of
their own — asked for by the command's flag, carried in the task, handed to start_run — and
`--no-fork-server` starts fresh interpreters everywhere. (That the rows are the same either
way: tests/test_experiment_slurm.py and tests/process/test_experiment_dask.py run with the
server, against the local backend's rows.)"""

from __future__ import annotations

from pathlib import Path

import pytest

from mrta_supervisor.experiment import api as experiment
from mrta_supervisor.experiment import dask_backend, slurm_backend
from mrta_supervisor.experiment.file import Run
from tests.test_experiment_runs import Ended, exp_file


@pytest.mark.parametrize("warm", [True, False])
def test_a_slurm_task_forks_its_run_from_a_server_of_its_own_when_asked(tmp_path, monkeypatch,
                                                                       warm):
    asked, finished = [], []

    def start_run(group, package, duration, run, out, plots=True, instance=None, warm=False):
        asked.append(warm)
        return Ended()
    monkeypatch.setattr(slurm_backend, "start_run", start_run)
    monkeypatch.setattr(slurm_backend, "inexact", lambda out: False)
    monkeypatch.setattr(slurm_backend.forkserver, "finish", lambda group: finished.append(group))
    run = Run(index=0, seed=1, failure="none", overrides=())
    result = slurm_backend.run_task(slurm_backend.SlurmTask(
        "patrol", 10.0, run, str(tmp_path / "run000"), False, warm))
    assert result.returncode == 0 and asked == [warm] and len(finished) == 1


@pytest.mark.parametrize("flag", [True, False])
@pytest.mark.parametrize("backend", ["slurm", "dask"])
def test_the_flag_reaches_the_cluster_backends(tmp_path, monkeypatch, flag, backend):
    seen = []
    monkeypatch.setattr(slurm_backend, "run_on_slurm", lambda **kw: seen.append(kw["warm"]))
    monkeypatch.setattr(dask_backend, "run_on_cluster", lambda _a, **kw: seen.append(kw["warm"]))
    monkeypatch.setattr(slurm_backend.SlurmOptions, "check", lambda self, output: None)
    monkeypatch.setattr(dask_backend, "require_distributed", lambda: None)  # not imported here
    where = ({"slurm": slurm_backend.SlurmOptions()} if backend == "slurm"
             else {"scheduler": "tcp://127.0.0.1:1"})
    experiment.run_experiment(file=exp_file(tmp_path), output=tmp_path / "o", plots=False,
                              warm=flag, **where)
    assert seen == [flag]


def test_a_dask_task_carries_the_flag(tmp_path: Path):
    run = Run(index=0, seed=1, failure="none", overrides=())
    assert dask_backend.RunTask("patrol", 10.0, run, "stop").warm  # on unless told otherwise
    assert not dask_backend.RunTask("patrol", 10.0, run, "stop", warm=False).warm
