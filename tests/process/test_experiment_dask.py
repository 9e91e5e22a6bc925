"""`mrta experiment --scheduler`: the runs of a matrix on a Dask cluster — a scheduler and two
workers started here on loopback (free ports, each `--nthreads 1 --resources runs=1`, as the
README says), ended by PID. The same rows as the local backend; a worker killed mid-sweep costs
no row and leaves no process behind; a Ctrl-C keeps exactly the finished rows."""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import importlib.util

import pytest

from mrta_zenoh.yamlfile import plural
from tests.harness.helpers import free_port

# distributed (and dask) imported where a cluster starts, not at collection: ≈ 0.7 CPU-s in
# every xdist worker's collection, for a module the CI tier deselects
pytestmark = [pytest.mark.multiprocess, pytest.mark.slow,
              pytest.mark.skipif(importlib.util.find_spec("distributed") is None,
                                 reason="no distributed (the `dask` extra)")]

MATRIX = "application: patrol\nduration: 20\nseeds: [1, 2]\nfailures: [robot2@10]\n"  # 2 runs
# what lockstep makes identical between two runs of one seed (not wall time, not traffic)
SAME = ("run", "config", "seed", "failure", "status", "takeover_seconds", "taken_over_by",
        "first_full_allocation")


# ------------------------------------------------------------------ processes, from /proc
def _stat(pid: int) -> list[str] | None:
    """/proc/PID/stat after the command name: [state, ppid, …, starttime at 19]."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except (OSError, IndexError):
        return None


def descendants(root: int) -> dict[int, str]:
    """Every live process under `root` → its start time (so a reused PID is not taken for it)."""
    parents: dict[int, list[int]] = {}
    starts: dict[int, str] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            st = _stat(int(entry.name))
            if st is not None and st[0] != "Z":
                parents.setdefault(int(st[1]), []).append(int(entry.name))
                starts[int(entry.name)] = st[19]
    out, todo = {}, [root]
    while todo:
        for kid in parents.get(todo.pop(), []):
            out[kid] = starts[kid]
            todo.append(kid)
    return out


def alive(pid: int, start: str) -> bool:
    st = _stat(pid)
    return st is not None and st[0] != "Z" and st[19] == start


def cmdline(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def demo_children(pid: int) -> list[int]:
    """`mrta demo` processes the worker `pid` started directly."""
    return [p for p, _ in descendants(pid).items()
            if (_stat(p) or ["", "0"])[1] == str(pid) and " demo " in cmdline(p)]


# ------------------------------------------------------------------ the cluster
class Cluster:
    """A scheduler and workers on 127.0.0.1, each a process of ours, ended by PID."""

    def __init__(self, folder: Path):
        self.folder = folder
        self.address = f"tcp://127.0.0.1:{free_port()}"
        self.procs: dict[str, subprocess.Popen] = {}
        self.env = dict(os.environ, PYTHONUNBUFFERED="1")

    def _start(self, name: str, *args: str) -> subprocess.Popen:
        log = (self.folder / f"{name}.log").open("w")
        proc = subprocess.Popen([sys.executable, "-m", *args], stdout=log,
                                stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env=self.env, cwd=self.folder)
        log.close()
        self.procs[name] = proc
        return proc

    def start(self, workers: int = 2, timeout: float = 30.0) -> None:
        port = self.address.rsplit(":", 1)[1]
        self._start("scheduler", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                    "--port", port, "--no-dashboard")
        # --no-nanny: the process started here is the one that runs the tasks (and is the
        # parent of their `mrta demo`), so killing it kills the worker, not a restartable child
        for i in range(workers):
            self._start(f"worker{i}", "distributed.cli.dask_worker", self.address,
                        "--host", "127.0.0.1", "--nthreads", "1", "--resources", "runs=1",
                        "--no-nanny", "--no-dashboard", "--name", f"worker{i}",
                        "--death-timeout", "20", "--local-directory",
                        str(self.folder / f"worker{i}"))
        import distributed
        with distributed.Client(self.address, timeout=timeout, set_as_default=False) as c:
            c.wait_for_workers(workers, timeout=timeout)

    def log(self, name: str) -> str:
        return (self.folder / f"{name}.log").read_text()[-3000:]

    def stop(self) -> None:
        """Workers, then the scheduler: SIGTERM, SIGKILL after 10 s; then whatever they had
        started that is still there, by its recorded PID."""
        left = {}
        for proc in self.procs.values():
            left.update(descendants(proc.pid))
        for name in sorted(self.procs, key=lambda n: n == "scheduler"):
            proc = self.procs[name]
            if proc.poll() is None:
                proc.terminate()
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(5)
        for pid, start in left.items():
            if alive(pid, start):
                os.kill(pid, signal.SIGKILL)


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    try:
        yield c
    finally:
        c.stop()


def rows_of(path: Path) -> list[dict]:
    return list(csv.DictReader(path.open())) if path.exists() else []


def who_did_what(out: Path, row: dict) -> dict:
    return json.loads((out / f"run{int(row['run']):03d}" / "summary.json").read_text())[
        "who_did_what"]


# ------------------------------------------------------------------ the tests
@pytest.mark.timeout(1500)
def test_the_cluster_gives_the_rows_of_the_local_backend(cluster, children, tmp_path):
    cluster.start(workers=2)
    f = tmp_path / "exp.yaml"
    f.write_text(MATRIX)
    t0 = time.monotonic()
    remote = children.mrta("experiment", f, "--output", tmp_path / "remote", "--scheduler",
                           cluster.address, name="remote")
    assert remote.wait(600) == 0, remote.tail(20) + cluster.log("scheduler")
    t1 = time.monotonic()
    local = children.mrta("experiment", f, "--output", tmp_path / "local", "--jobs", "2",
                          name="local")
    assert local.wait(600) == 0, local.tail(20)
    print(f"cluster {t1 - t0:.1f} s, local {time.monotonic() - t1:.1f} s")
    a, b = rows_of(tmp_path / "remote" / "results.csv"), rows_of(tmp_path / "local" / "results.csv")
    assert len(a) == len(b) == 2 and list(a[0]) == list(b[0])  # the same columns, in order
    coverage = [k for k in a[0] if k.endswith((".exactly_one", ".none", ".more_than_one"))
                or k.startswith("metrics.")]
    assert coverage
    for ra, rb in zip(a, b):
        assert {k: ra[k] for k in SAME + tuple(coverage)} == \
            {k: rb[k] for k in SAME + tuple(coverage)}, (ra, rb)
        assert ra["status"] == "ok", ra  # (a failed run's row: tests/test_experiment.py)
        assert ra["taken_over_by"] in ("robot1", "robot3"), ra  # a takeover to compare
        assert who_did_what(tmp_path / "remote", ra) == who_did_what(tmp_path / "local", rb)
        folder = tmp_path / "remote" / f"run{int(ra['run']):03d}"
        assert {p.name for p in folder.iterdir()} >= {"run.mcap", "summary.json"}
        # the pictures: drawn by the first run of the cell only, on the worker as here
        assert ("timeline.png" in {p.name for p in folder.iterdir()}) == (ra["run"] == "0")
        summary = json.loads((folder / "summary.json").read_text())
        assert summary["output"] == str(folder)  # here, not the worker's scratch folder
    assert (tmp_path / "remote" / "summary.md").read_text().count("fail=robot2@10") >= 1
    assert (tmp_path / "remote" / "takeover.png").stat().st_size > 5_000


@pytest.mark.timeout(1200)
def test_a_matrix_of_instances_and_architectures_gives_the_rows_of_the_local_backend(
        cluster, children, tmp_path):
    """The workers get each run's instance file with the task (they may be other machines):
    the rows are the local backend's, but wall time."""
    cluster.start(workers=2)
    f = tmp_path / "exp.yaml"
    f.write_text("application: delivery\nduration: 12\nseeds: [1]\n"
                 "architectures: [alliance, murdoch]\nfailures: [\"stall:@first@3\"]\n"
                 "instances:\n  generator: delivery\n  robots: [3]\n  seed: 4\n")
    for where, how in (("remote", ["--scheduler", cluster.address]), ("local", ["--jobs", "2"])):
        run = children.mrta("experiment", f, "--output", tmp_path / where, "--no-plots", *how,
                            name=where)
        assert run.wait(600) == 0, run.tail(20) + cluster.log("scheduler")
    a, b = rows_of(tmp_path / "remote" / "results.csv"), rows_of(tmp_path / "local" / "results.csv")
    assert len(a) == 2 and list(a[0]) == list(b[0])
    assert [{k: v for k, v in r.items() if k != "wall_seconds"} for r in a] == \
        [{k: v for k, v in r.items() if k != "wall_seconds"} for r in b]
    assert [(r["architecture"], r["instance"], r["status"]) for r in a] == [
        ("alliance", "delivery-r3-t3-4", "ok"), ("murdoch", "delivery-r3-t3-4", "ok")]
    assert all(r["failed_robot"] for r in a)  # @first resolved on the workers as here
    for r in a:
        summary = json.loads((tmp_path / "remote" / f"run{int(r['run']):03d}" / "summary.json")
                             .read_text())
        assert summary["instance"]["name"] == "delivery-r3-t3-4"


@pytest.mark.timeout(1200)
def test_a_run_whose_worker_is_killed_runs_again_elsewhere_and_its_processes_end(
        cluster, children, tmp_path):
    cluster.start(workers=2)
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 20\nseeds: [1, 2]\nfailures: [robot2@10]\n")
    exp = children.mrta("experiment", f, "--output", tmp_path / "out", "--scheduler",
                        cluster.address, name="experiment")
    workers = {n: p for n, p in cluster.procs.items() if n.startswith("worker")}
    # a worker whose run is under way: its `mrta demo` has started the mission's processes
    # (simulator, three agents, recorder)
    victim, tree, deadline = None, {}, time.monotonic() + 300
    while victim is None:
        assert time.monotonic() < deadline, exp.tail(20)
        for name, proc in workers.items():
            demos = demo_children(proc.pid)
            if demos and any(len(descendants(d)) >= 4 for d in demos):
                victim, tree = name, descendants(proc.pid)
                break
        time.sleep(0.2)
    workers[victim].send_signal(signal.SIGKILL)
    workers[victim].wait(5)
    t_kill = time.monotonic()
    # the run's processes follow their worker: none of them is left after a few seconds
    deadline = time.monotonic() + 60
    while any(alive(p, s) for p, s in tree.items()) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = {p: cmdline(p) for p, s in tree.items() if alive(p, s)}
    assert not left, f"processes of the killed worker still running: {left}"
    gone_after = time.monotonic() - t_kill
    assert exp.wait(600) == 0, exp.tail(20) + cluster.log("scheduler")
    rows = rows_of(tmp_path / "out" / "results.csv")
    assert sorted(int(r["run"]) for r in rows) == [0, 1], rows
    assert all(r["status"] == "ok" and r["taken_over_by"] for r in rows), rows
    print(f"killed {victim}: its {len(tree)} processes gone in {gone_after:.1f} s")


@pytest.mark.timeout(900)
def test_ctrl_c_keeps_exactly_the_finished_rows_and_stops_the_runs(cluster, children, tmp_path):
    cluster.start(workers=2)
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 12\nseeds: [1, 2, 3, 4]\nfailures: [none]\n")
    out = tmp_path / "out"
    exp = children.mrta("experiment", f, "--output", out, "--scheduler", cluster.address,
                        name="experiment")
    deadline = time.monotonic() + 300
    while not rows_of(out / "results.csv"):
        assert time.monotonic() < deadline and exp.running(), exp.tail(20)
        time.sleep(0.1)
    exp.signal(signal.SIGINT)
    assert exp.wait(120) == 130, exp.tail(20)
    rows = rows_of(out / "results.csv")
    assert 1 <= len(rows) < 4 and all(r["status"] == "ok" for r in rows), rows
    assert {p.name for p in out.iterdir() if p.name.startswith("run0")} == {
        f"run{int(r['run']):03d}" for r in rows}  # a folder for each kept row, no other
    assert f"{plural(len(rows), 'run')} of" in (out / "summary.md").read_text()
    # the runs under way stop on the workers (the stop event), not at the end of their mission
    deadline = time.monotonic() + 60
    while any(demo_children(p.pid) for p in cluster.procs.values()):
        assert time.monotonic() < deadline, {n: demo_children(p.pid)
                                             for n, p in cluster.procs.items()}
        time.sleep(0.2)
