"""Resuming `mrta experiment` across processes, for real: a run of a 2-run patrol matrix killed
by PID (SIGKILL: no handler runs) while its second mission is under way, then the same command
again — it runs only the missing runs and ends with the rows of an uninterrupted run (but the
machine's columns, results.MACHINE_TIME); the killed run's missions end with their parent."""

from __future__ import annotations

import csv
import os
import signal
import time
from pathlib import Path

import pytest

from mrta_supervisor.experiment.results import MACHINE_TIME
from tests.harness.helpers import descendants

pytestmark = pytest.mark.multiprocess

MATRIX = "application: patrol\nduration: 10\nseeds: [1, 2]\nfailures: [robot2@5]\n"
RUNS = 2  # enough for one run kept and one resumed (each patrol run is ≈ 9 CPU-s)


def rows(folder: Path) -> list[dict]:
    path = folder / "results.csv"
    return list(csv.DictReader(path.open())) if path.is_file() else []


def same(table: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in MACHINE_TIME} for r in table]


def differ(a: list[dict], b: list[dict]) -> list[dict]:
    """Per row, the columns whose values differ (for the assertion's message)."""
    return [{k: (x.get(k), y.get(k)) for k in {*x, *y} if x.get(k) != y.get(k)}
            for x, y in zip(a, b)]


@pytest.mark.timeout(900)
def test_a_run_killed_midway_resumes_to_the_uninterrupted_rows(children, tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text(MATRIX)
    out = tmp_path / "out"
    args = ("experiment", f, "--output", out, "--jobs", "1", "--no-plots")
    first = children.mrta(*args, name="killed")
    deadline = time.monotonic() + 600
    while len(rows(out)) < 1:  # the first run's row is written: the second run is under way
        assert time.monotonic() < deadline and first.running(), first.tail(20)
        time.sleep(0.1)
    below = descendants(first.proc.pid)
    os.kill(first.proc.pid, signal.SIGKILL)
    first.wait(30)
    kept = rows(out)
    assert 1 <= len(kept) < RUNS, kept
    # its missions stop once their parent is gone (lifecycle.die_with_parent)
    deadline = time.monotonic() + 60
    while any(Path(f"/proc/{p}").exists() and "Z" not in _state(p) for p in below):
        assert time.monotonic() < deadline, [p for p in below if Path(f"/proc/{p}").exists()]
        time.sleep(0.2)
    resumed = children.mrta(*args, name="resumed")
    assert resumed.wait(600) == 0, resumed.tail(20)
    ran = [line for line in resumed.stderr if line.startswith("[")]
    assert len(ran) == RUNS - len(kept), ran  # only the missing runs ran
    got = rows(out)
    assert sorted(int(r["run"]) for r in got) == list(range(RUNS))  # 0 duplicates, 0 missing
    assert [r["status"] for r in got] == ["ok"] * RUNS, got
    whole = children.mrta("experiment", f, "--output", tmp_path / "whole", "--jobs", "2",
                          "--no-plots", name="uninterrupted")
    assert whole.wait(600) == 0, whole.tail(20)
    assert same(got) == same(rows(tmp_path / "whole")), differ(got, rows(tmp_path / "whole"))
    assert all(r["metrics.border_visited"] and r["wander.exactly_one"] for r in got)  # measured


def _state(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return "Z"
