"""The delivery study end to end: an online instance generated, run under both
architectures, its summary carrying the offline optimum with hindsight and no task started
before it arrived; and the same seed giving a byte-identical results.csv (the wall time
aside)."""

from __future__ import annotations

import csv
import io
import json
import math
import random
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

ONLINE = "delivery_study_online"  # not a shipped name: the generated packages live in tmp


def generate_online(dest: Path) -> None:
    """`python -m mrta_delivery.generate_cli --arrivals poisson` into `dest` (4 tasks arriving
    at 1.6, 3.0, 5.9 and 15.2 s with rate 0.2 and seed 7: `poisson_arrivals` below)."""
    done = subprocess.run([sys.executable, "-m", "mrta_delivery.generate_cli", "--name", ONLINE,
                           "--arrivals", "poisson", "--rate", "0.2", "--seed", "7",
                           "--output", str(dest)], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (dest / ONLINE / "package.xml").is_file()
    assert (dest / f"{ONLINE}_murdoch" / "package.xml").is_file()


def poisson_arrivals(seed: int, rate: float, n: int) -> list[float]:
    """A Poisson process by its definition: exponential gaps by inverse transform of the
    generator's own stream (`random.Random("mrta.instances/poisson/<seed>")`), cumulated."""
    rng, t, out = random.Random(f"mrta.instances/poisson/{seed}"), 0.0, []
    for _ in range(n):
        t += -math.log(1.0 - rng.random()) / rate
        out.append(round(t, 3))
    return out


def hindsight_optimum(cost: list[list[float | None]]) -> float:
    """The minimum-cost assignment of the whole instance, known in advance (None: cannot)."""
    # imported here, not at collection: scipy.optimize costs ≈ 0.8 CPU-s in every xdist
    # worker's collection, for a module the CI tier deselects
    import numpy as np
    from scipy.optimize import linear_sum_assignment
    c = np.array([[np.inf if x is None else x for x in row] for row in cost])
    big = np.where(np.isfinite(c), c, 1e9)
    rows, cols = linear_sum_assignment(big)
    return float(sum(c[i, j] for i, j in zip(rows, cols) if np.isfinite(c[i, j])))


@pytest.mark.timeout(600)
@pytest.mark.parametrize("package", [ONLINE, f"{ONLINE}_murdoch"])
def test_an_online_instance_runs_under_both_architectures_and_is_measured_with_hindsight(
        children, tmp_path, package):
    packages = tmp_path / "packages"
    generate_online(packages)
    children.env["MRTA_PACKAGE_PATH"] = str(packages)
    out = tmp_path / "run"
    s = children.demo(out, "--application", package, "--duration", "60", "--seed", "2",
                      quiet=True).summary(300)
    assert s["mission"] == "delivery" and s["application"] == package and s["lockstep"] is True
    assert s["architecture"] == ("murdoch" if package.endswith("_murdoch") else "alliance")
    m = s["metrics"]
    print(package, json.dumps(m))
    assert m["online"] is True
    arrival = {tid: t["arrival"] for tid, t in s["instance"]["tasks"].items()}
    assert sorted(arrival.values()) == pytest.approx(poisson_arrivals(7, 0.2, 4))
    # the offline optimum with hindsight: the whole instance's best assignment, arrivals known
    assert m["optimal_cost"] == pytest.approx(hindsight_optimum(s["instance"]["cost"]), abs=1e-3)
    assert m["completed"] == m["tasks"] == 4
    assert 0 < m["optimality"] <= 1
    assert s["allocation"], s
    for e in s["allocation"]:  # nobody is assigned, nor starts, a task before it exists
        assert e["assigned_at"] >= arrival[e["task"]] - 1e-6, e
        if e["started_at"] is not None:
            assert e["started_at"] >= e["assigned_at"] >= arrival[e["task"]], e
    waits = [min(e["started_at"] for e in s["allocation"] if e["task"] == t
                 and e["started_at"] is not None) - arrival[t] for t in arrival]
    assert m["mean_waiting_time"] == pytest.approx(sum(waits) / len(waits), abs=2e-3)


def csv_without(data: bytes, column: str) -> list[list[str]]:
    rows = list(csv.reader(io.StringIO(data.decode())))
    i = rows[0].index(column)
    return [r[:i] + r[i + 1:] for r in rows]


@pytest.mark.timeout(600)
def test_the_same_seed_gives_a_byte_identical_results_csv(children, tmp_path):
    """Two `mrta experiment` runs of one delivery seed, lockstep: results.csv is the same byte
    for byte but the `wall_seconds` column (wall time is the machine's, not the run's). No
    column names the output folder (a summary's `output` is not a results.csv column)."""
    f = tmp_path / "exp.yaml"
    f.write_text("application: delivery\narchitecture: murdoch\nduration: 40\nseeds: [3]\n"
                 "failures: [\"loss:0.2\"]\n")
    files = []
    for name in ("a", "b"):
        out = tmp_path / name
        run = children.mrta("-q", "experiment", f, "--output", out, "--jobs", "1",
                            name=f"experiment {name}")
        assert run.wait(280) == 0, run.stderr[-10:] + run.stdout[-10:]
        files.append((out / "results.csv").read_bytes())
        summary = json.loads((out / "run000" / "summary.json").read_text())
        assert summary["faults"] == "loss:0.2" and summary["lockstep_exact"] is True
    a, b = (csv_without(x, "wall_seconds") for x in files)
    assert a == b
    header, row = a
    assert len(a) == 2 and dict(zip(header, row))["status"] == "ok"
    assert not any(str(tmp_path) in cell for cell in row)
    # byte for byte: every line equal once the wall-time cell is cut out of it (the csv module
    # writes the same cells the same way, so this is the bytes' comparison without that cell)
    la, lb = (x.split(b"\r\n") for x in files)
    assert la[0] == lb[0] and len(la) == len(lb) == 3
