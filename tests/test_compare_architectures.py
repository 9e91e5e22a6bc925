"""`python benchmarks/compare_architectures.py`, the architecture study: its matrix is the one
it says (generated instances, sizes crossed, role-named faults), its tables come from the
experiment report (docs/statistics.md) with every objective beside its reference, and it writes
docs/comparison.md and the README only when asked (`--write-docs`)."""

from __future__ import annotations

import csv
import importlib.util
import json
import sys
from pathlib import Path

import pytest

from mrta_zenoh.errors import ConfigError
from mrta_supervisor.experiment.file import load_experiment
from tests.harness.helpers import ROOT

TAKEOVER = {"alliance": [3.05, 3.10, 3.05], "murdoch": [2.30, 2.30, 2.30]}


def study():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location(
        "compare_architectures", ROOT / "benchmarks" / "compare_architectures.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def write_rows(folder: Path, rows: list[dict]) -> None:
    folder.mkdir(parents=True)
    columns = list(dict.fromkeys(k for r in rows for k in r))
    with (folder / "results.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=columns)
        w.writeheader()
        w.writerows(rows)


def patrol_results(out: Path) -> None:
    """patrol under both architectures, faults none and crash, three seeds, written as results
    were before rows named their architecture (the study adds it)."""
    for arch, overrides in (("alliance", {"robot*.broadcast_rate": 2.0}),
                            ("murdoch", {"robot*.renewal_period": 0.5})):
        rows = []
        for fail in ("none", "robot2@20"):
            for i, seed in enumerate((1, 2, 3)):
                rows.append({"run": len(rows), "config": f"fail={fail}", "seed": seed,
                             "failure": fail, "status": "ok", "error": "", "wall_seconds": 9.0,
                             **overrides,
                             "takeover_seconds": TAKEOVER[arch][i] if fail != "none" else "",
                             "wander.exactly_one": 0.99, "first_full_allocation": 0.6,
                             "coordination_messages_per_second": 4.4 if arch == "alliance"
                             else 5.1})
        write_rows(out / f"patrol_{arch}", rows)


# (architecture, instance) → (objective_minsum, completed); the reference minsum per instance
MINSUM = {("alliance", "i1"): (12.0, 3), ("alliance", "i2"): (None, 2),
          ("central", "i1"): (10.0, 3), ("central", "i2"): (9.0, 3)}
REFERENCE = {"i1": 8.0, "i2": 9.0}


def delivery_results(out: Path) -> None:
    """Two architectures on two 3-robot instances, no fault, one seed; ALLIANCE leaves a task
    of i2 unserved (no objective value there)."""
    for arch in ("alliance", "central"):
        rows = []
        for inst in ("i1", "i2"):
            minsum, completed = MINSUM[arch, inst]
            rows.append({"run": len(rows), "config": "", "seed": 1, "mission": "delivery",
                         "instance": inst, "n_robots": 3, "n_tasks": 3, "failure": "none",
                         "status": "ok", "error": "", "wall_seconds": 20.0,
                         "metrics.completed": completed,
                         "metrics.objective_minsum": "" if minsum is None else minsum,
                         "metrics.reference_minsum": REFERENCE[inst],
                         "metrics.reference_proven_optimal": True,
                         "coordination_messages_per_second": 2.0})
        write_rows(out / f"delivery_{arch}", rows)


def docs(tmp_path: Path) -> tuple[Path, Path]:
    doc, readme = tmp_path / "comparison.md", tmp_path / "README.md"
    doc.write_text("intro\n<!-- table: begin -->\nold table\n<!-- table: end -->\nby hand\n")
    readme.write_text("top\n<!-- study: begin -->\nold headline\n<!-- study: end -->\n")
    return doc, readme


def test_the_matrix_is_generated_instances_sizes_crossed_and_role_named_faults(tmp_path):
    mod = study()
    args = mod.parse(["--robots", "3", "5", "--tasks-per-robot", "1", "2", "--instances", "2",
                      "--seeds", "1", "2"])
    path = tmp_path / "delivery_ssi.yaml"
    path.write_text(json.dumps(mod.delivery_experiment("ssi", args)))  # JSON is YAML
    exp = load_experiment(path)  # the experiment's own checks: generator, faults, sizes
    every = ["none", "crash:@first@5", "stall:@first@5", "partition:@first@5+10", "loss:0.2",
             "latency:0.5+-0.2", "range:4"]
    assert exp.spec.failures == every  # no dispatcher to crash: not run at all
    # 2 team sizes × 2 task counts × 2 instances × 7 faults × 2 seeds
    assert exp.count() == 2 * 2 * 2 * 7 * 2
    assert exp.spec.architecture == "ssi" and exp.spec.instances.generator == "delivery"
    path.write_text(json.dumps(mod.delivery_experiment("central", args)))
    assert load_experiment(path).spec.failures == every + ["crash:dispatcher@5"]


def test_delivery_tables_put_each_objective_beside_its_reference(tmp_path, capsys):
    out = tmp_path / "study"
    delivery_results(out)
    args = ["--reuse", "--output", str(out), "--missions", "delivery", "--large-robots",
            "--architectures",
            "alliance", "central", "--faults", "none", "--robots", "3", "--no-plots"]
    assert study().main(args) == 0
    with (out / "delivery" / "results.csv").open(newline="") as f:
        rows = {(r["architecture"], r["instance"]): r for r in csv.DictReader(f)}
    for (arch, inst), (minsum, _) in MINSUM.items():
        gap = rows[arch, inst]["metrics.gap_minsum"]
        if minsum is None:
            assert gap == ""  # no objective value: no gap, never 0
        else:
            assert float(gap) == pytest.approx((minsum / REFERENCE[inst] - 1) * 100)
        assert float(rows[arch, inst]["metrics.reference_objective_minsum"]) == REFERENCE[inst]
    tables = (out / "tables.md").read_text()
    # central's gaps: 25 % on i1, 0 % on i2 → mean 12.5 %; ALLIANCE's: 50 % on i1, i2 missing
    assert "| 3 | 3 | central | 2/2 |" in tables and "| 12.50 [" in tables
    assert "50.00 (1 run); missing in 1 of 2" in tables
    assert "#### Paired against central" in tables and "proven optimal" in tables
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    paired = next(x for x in lines if x.get("figure") == "metrics.gap_minsum"
                  and "other" in x)
    assert paired["other"] == "alliance" and paired["pairs"] == 1
    assert paired["other_minus_baseline"] == pytest.approx(50.0 - 25.0)


def test_the_study_writes_its_tables_into_its_output_only_unless_asked(tmp_path, capsys):
    out = tmp_path / "study"
    patrol_results(out)
    doc, readme = docs(tmp_path)
    before = doc.read_text(), readme.read_text()
    args = ["--reuse", "--output", str(out), "--missions", "patrol", "--faults", "none",
            "crash", "--patrol-seeds", "1", "2", "3", "--no-plots", "--doc", str(doc),
            "--readme", str(readme)]
    assert study().main(args) == 0
    assert (doc.read_text(), readme.read_text()) == before
    tables = (out / "tables.md").read_text()
    # the report's words and figures: ALLIANCE − MURDOCH paired by seed, Wilcoxon, A12
    assert "murdoch → alliance" in tables and "Holm family" in tables
    assert "2.30 (identical in every run)" in tables
    assert "| patrol | robot2@20 | 3 / 3 | takeover (s) | 3.07 [" in tables
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    crash = next(x for x in lines if x.get("figure") == "takeover_seconds" and x.get("pairs"))
    expected = sum(a - m for a, m in zip(TAKEOVER["alliance"], TAKEOVER["murdoch"])) / 3
    assert crash["pairs"] == 3 and crash["other_minus_baseline"] == pytest.approx(expected,
                                                                                   abs=1e-4)
    assert lines[-1]["docs_rewritten"] == []

    assert study().main(args + ["--write-docs"]) == 0
    assert "murdoch → alliance" in doc.read_text() and "old table" not in doc.read_text()
    assert doc.read_text().endswith("<!-- table: end -->\nby hand\n")
    assert "| patrol | robot2@20 |" in readme.read_text()


def test_reuse_refuses_results_of_another_matrix(tmp_path):
    out = tmp_path / "study"
    patrol_results(out)
    (out / "patrol_alliance.yaml").write_text("application: patrol\nduration: 30.0\n")
    with pytest.raises(ConfigError, match="another matrix"):
        study().main(["--reuse", "--output", str(out), "--missions", "patrol", "--no-plots"])


def fault_results(out: Path) -> None:
    """ALLIANCE and central on two 3-robot instances: without a fault and under loss (ALLIANCE's
    loss run of i2 ends later than its faultless one, every other ends the same), and central
    also under its dispatcher's crash."""
    for arch in ("alliance", "central"):
        rows = []
        failures = ["none", "loss:0.2"] + (["crash:dispatcher@5"] if arch == "central" else [])
        for fail in failures:
            for inst in ("i1", "i2"):
                late = arch == "alliance" and fail == "loss:0.2" and inst == "i2"
                rows.append({"run": len(rows), "config": "", "seed": 1, "mission": "delivery",
                             "instance": inst, "n_robots": 3, "n_tasks": 3, "failure": fail,
                             "status": "ok", "error": "", "wall_seconds": 20.0,
                             "metrics.completed": 3, "metrics.makespan": 30.0 if late else 20.0,
                             "metrics.objective_minsum": 10.0, "metrics.reference_minsum": 8.0,
                             "metrics.reference_proven_optimal": True,
                             "coordination_messages_per_second": 2.0})
        write_rows(out / f"delivery_{arch}", rows)


def test_each_faults_rows_say_what_did_not_apply_and_what_it_changed(tmp_path):
    out = tmp_path / "study"
    fault_results(out)
    args = ["--reuse", "--output", str(out), "--missions", "delivery", "--large-robots",
            "--architectures",
            "alliance", "central", "--faults", "none", "loss", "dispatcher", "--robots", "3",
            "--tasks-per-robot", "1", "--instances", "2", "--no-plots"]
    assert study().main(args) == 0
    tables = (out / "tables.md").read_text()
    loss = tables.split("#### loss:0.2")[1].split("####")[0]
    assert "| 3 | 3 | alliance | 2/2 |" in loss and loss.count("| 1 of 2 |") == 1
    assert "| 3 | 3 | central | 2/2 |" in loss and loss.count("| every run |") == 1
    dispatcher = tables.split("#### crash:dispatcher@5")[1].split("####")[0]
    assert "| 3 | 3 | alliance | n/a: no dispatcher to crash (not run) |" in dispatcher
    assert "| 3 | 3 | central | 2/2 |" in dispatcher
    with (out / "delivery" / "results.csv").open(newline="") as f:
        per_robot = [float(r["metrics.coordination_per_robot"]) for r in csv.DictReader(f)]
    assert len(per_robot) == 10 and per_robot == [pytest.approx(2.0 / 3, abs=1e-4)] * 10


def test_larger_teams_join_deliverys_report_as_runs_of_their_own(tmp_path):
    out = tmp_path / "study"
    delivery_results(out)
    for arch in ("alliance", "central"):
        write_rows(out / f"large_{arch}", [
            {"run": 0, "config": "", "seed": 1, "mission": "delivery", "instance": "big",
             "n_robots": 10, "n_tasks": 10, "failure": "none", "status": "ok", "error": "",
             "wall_seconds": 60.0, "metrics.completed": 10 if arch == "central" else 9,
             "coordination_messages_per_second": 5.0}])
    args = ["--reuse", "--output", str(out), "--missions", "delivery", "--large-robots", "10",
            "--large-faults", "none", "--architectures", "alliance", "central", "--faults",
            "none", "--robots", "3", "--tasks-per-robot", "1", "--no-plots"]
    assert study().main(args) == 0
    with (out / "delivery" / "results.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(int(r["run"]) for r in rows if r["n_robots"] == "10") == [100_000, 100_000]
    assert len({(r["architecture"], r["run"]) for r in rows}) == len(rows) == 6
    tables = (out / "tables.md").read_text()
    assert "| 10 | 10 | central | 1/1 | 10.00 (1 run) |" in tables
    assert "| 10 | 10 | alliance | 1/1 | 9.00 (1 run) |" in tables
    assert "Larger teams beside them, N = 10" in tables
