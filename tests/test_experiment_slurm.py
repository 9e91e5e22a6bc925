"""`mrta experiment run --backend slurm` against a real single-node SLURM: Debian's munged,
slurmctld and slurmd started here from a slurm.conf written for 127.0.0.1 (free ports, its own
munge key and socket, no accounting), each a process of ours ended by PID. The cluster's
MaxArraySize is 2, so a 3-run matrix goes in two arrays; the rows are the local backend's (but
the machine's columns). Without root, or without the daemons (`.ci/run` installs them: apt's
slurmctld, slurmd, slurm-client and munge), the test skips and says which."""

from __future__ import annotations

import csv
import os
import shutil
import signal
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_supervisor.experiment import slurm_backend as experiment_slurm
from mrta_supervisor.experiment.results import MACHINE_TIME
from tests.harness.helpers import free_port

MATRIX = "application: patrol\nduration: 10\nseeds: [1, 2, 3]\nfailures: [robot2@5]\n"
DAEMONS = ("munged", "slurmctld", "slurmd", "sbatch", "scontrol", "squeue", "srun")
MAX_ARRAY = 2


def slurm_conf(folder: Path, host: str) -> str:
    return f"""\
ClusterName=mrtatest
SlurmctldHost={host}(127.0.0.1)
SlurmctldPort={free_port()}
SlurmdPort={free_port()}
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket={folder}/munge.sock
CredType=cred/munge
StateSaveLocation={folder}/state
SlurmdSpoolDir={folder}/spool
SlurmctldPidFile={folder}/slurmctld.pid
SlurmdPidFile={folder}/slurmd.pid
SlurmctldLogFile={folder}/slurmctld.log
SlurmdLogFile={folder}/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
ReturnToService=2
MaxArraySize={MAX_ARRAY}
NodeName={host} NodeAddr=127.0.0.1 CPUs={os.cpu_count() or 1} State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
"""


class Slurm:
    """munged, slurmctld and slurmd in the foreground, each a child of this test."""

    def __init__(self) -> None:
        # a short path: the munge socket's must fit a sockaddr_un (108 bytes)
        self.folder = Path(tempfile.mkdtemp(prefix="mrta-slurm-"))
        self.procs: dict[str, subprocess.Popen] = {}
        self.conf = self.folder / "slurm.conf"
        self.env = dict(os.environ, SLURM_CONF=str(self.conf))

    def _start(self, name: str, *argv: str) -> None:
        log = (self.folder / f"{name}.out").open("w")
        self.procs[name] = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                            stdin=subprocess.DEVNULL, env=self.env)
        log.close()

    def start(self) -> None:
        for sub in ("state", "spool"):
            (self.folder / sub).mkdir()
        key = self.folder / "munge.key"
        key.write_bytes(os.urandom(1024))
        key.chmod(0o600)
        self.conf.write_text(slurm_conf(self.folder, socket.gethostname().split(".")[0]))
        self._start("munged", "munged", "-F", "-f", f"--socket={self.folder}/munge.sock",
                    f"--key-file={key}", f"--pid-file={self.folder}/munged.pid",
                    f"--seed-file={self.folder}/munged.seed",
                    f"--log-file={self.folder}/munged.log")
        self._wait(lambda: (self.folder / "munge.sock").exists(), "munged's socket")
        self._start("slurmctld", "slurmctld", "-D", "-c", "-f", str(self.conf))
        self._start("slurmd", "slurmd", "-D", "-f", str(self.conf))
        self._wait(self._idle, "the node idle in sinfo")

    def _idle(self) -> bool:
        out = subprocess.run(["sinfo", "-h", "-o", "%t"], capture_output=True, text=True,
                             env=self.env)
        return out.returncode == 0 and out.stdout.strip() == "idle"

    def _wait(self, cond, what: str, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while not cond():
            for name, proc in self.procs.items():
                assert proc.poll() is None, f"{name} exited {proc.returncode}: {self.log(name)}"
            assert time.monotonic() < deadline, f"no {what}: {self.log('slurmctld')}"
            time.sleep(0.2)

    def log(self, name: str) -> str:
        text = ""
        for f in (self.folder / f"{name}.out", self.folder / f"{name}.log"):
            if f.is_file():
                text += f.read_text()[-2000:]
        return text

    def stop(self) -> None:
        """The daemons by PID, slurmd first: SIGTERM, SIGKILL after 10 s."""
        for name in ("slurmd", "slurmctld", "munged"):
            proc = self.procs.get(name)
            if proc is None or proc.poll() is not None:
                continue
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        shutil.rmtree(self.folder, ignore_errors=True)


@pytest.fixture
def slurm():
    pytest.importorskip("submitit")
    if os.geteuid() != 0:
        pytest.skip("a test SLURM's slurmd runs as root: not root here")
    missing = [d for d in DAEMONS if shutil.which(d) is None]
    if missing:
        pytest.skip(f"no {', '.join(missing)}: apt-get install slurmctld slurmd slurm-client "
                    "munge (.ci/run does)")
    cluster = Slurm()
    try:
        cluster.start()
        yield cluster
    finally:
        cluster.stop()


def rows(folder: Path) -> list[dict]:
    return list(csv.DictReader((folder / "results.csv").open()))


def same(table: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in MACHINE_TIME} for r in table]


def differ(a: list[dict], b: list[dict]) -> list[dict]:
    """Per row, the columns whose values differ (for the assertion's message)."""
    return [{k: (x.get(k), y.get(k)) for k in {*x, *y} if x.get(k) != y.get(k)}
            for x, y in zip(a, b)]


@pytest.mark.multiprocess
@pytest.mark.timeout(900)
def test_slurm_job_arrays_give_the_rows_of_the_local_backend(slurm, children, tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text(MATRIX)
    children.env["SLURM_CONF"] = str(slurm.conf)
    remote = children.mrta("experiment", "run", f, "--output", tmp_path / "slurm",
                           "--backend", "slurm", "--no-plots", name="slurm")
    assert remote.wait(600) == 0, remote.tail(20) + slurm.log("slurmctld")
    local = children.mrta("experiment", f, "--output", tmp_path / "local", "--jobs", "2",
                          "--no-plots", name="local")
    assert local.wait(600) == 0, local.tail(20)
    got = rows(tmp_path / "slurm")
    assert [r["status"] for r in got] == ["ok"] * 3, got
    assert same(got) == same(rows(tmp_path / "local")), differ(got, rows(tmp_path / "local"))
    # no array larger than the cluster's MaxArraySize: 3 runs went in an array of 2 and a job
    # of 1 (submitit submits a single task as a plain job): submitit's folders, JOB for a job
    # or an array, JOB_TASK for an array's task
    jobs = {p.name for p in (tmp_path / "slurm" / "slurm").iterdir()
            if not p.name.startswith(".")}
    first, second = sorted({j.split("_")[0] for j in jobs}, key=int)
    assert jobs == {first, f"{first}_0", f"{first}_1", second}, jobs


@pytest.mark.parametrize("args,says", [
    (["--partition", "debug"], "--partition is for --backend slurm"),
    (["--backend", "local", "--array-size", "4"], "--array-size is for --backend slurm"),
    (["--backend", "slurm", "--jobs", "2"], "--jobs (this machine)"),
    (["--backend", "dask"], "--backend dask needs --scheduler"),
    (["--backend", "slurm", "--scheduler", "tcp://127.0.0.1:1"], "--scheduler is the Dask"),
    (["--backend", "slurm", "--array-size", "0"], "--array-size"),
])
def test_backend_usage_errors_exit_2_in_one_line_before_anything_is_written(tmp_path, args,
                                                                            says):
    f = tmp_path / "exp.yaml"
    f.write_text(MATRIX)
    res = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o"), *args])
    assert res.exit_code == 2 and says in res.output, res.output
    assert "Traceback" not in res.output and not (tmp_path / "o").exists()


def test_without_slurm_or_submitit_the_backend_says_what_is_missing(tmp_path, monkeypatch):
    f = tmp_path / "exp.yaml"
    f.write_text(MATRIX)
    monkeypatch.setattr(experiment_slurm.shutil, "which", lambda name: None)
    res = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o"),
                                   "--backend", "slurm"])
    assert res.exit_code == 2 and "no SLURM here" in res.output, res.output
    monkeypatch.setitem(__import__("sys").modules, "submitit", None)
    res = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o"),
                                   "--backend", "slurm"])
    assert res.exit_code == 2 and "pip install 'mrta-zenoh[slurm]'" in res.output, res.output
    assert not (tmp_path / "o").exists()


def test_runs_go_in_arrays_no_larger_than_asked():
    from mrta_supervisor.experiment.file import Run
    runs = [Run(i, 1, "none", ()) for i in range(7)]
    parts = experiment_slurm.chunks(runs, 3)
    assert [[r.index for r in p] for p in parts] == [[0, 1, 2], [3, 4, 5], [6]]


@pytest.mark.multiprocess
def test_a_folder_whose_earlier_tasks_still_run_is_refused_naming_them(tmp_path, monkeypatch):
    """This process killed, its tasks go on: a second run into the folder would write the same
    run folders. Stand-in scontrol, sbatch and squeue (squeue lists two tasks of the job name)."""
    pytest.importorskip("submitit")
    bin_ = tmp_path / "bin"
    bin_.mkdir()
    out = tmp_path / "o"
    name = experiment_slurm.job_name(out)
    for tool, body in (("scontrol", "echo 'MaxArraySize            = 4'"), ("sbatch", "exit 1"),
                       ("squeue", f'case "$*" in *"-n {name}"*) printf "7_0\\n7_1\\n";; esac')):
        (bin_ / tool).write_text(f"#!/bin/sh\n{body}\n")
        (bin_ / tool).chmod(0o755)
    monkeypatch.setenv("PATH", f"{bin_}:{os.environ['PATH']}")
    f = tmp_path / "exp.yaml"
    f.write_text(MATRIX)
    res = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(out), "--backend",
                                   "slurm"])
    assert res.exit_code == 2, res.output
    assert "2 SLURM tasks of an earlier run" in res.output and f"scancel --name {name}" in \
        res.output and len(res.output.strip().splitlines()) == 1
    assert not out.exists()
