"""`python benchmarks/compare_architectures.py`: its tables come from the experiment report
(docs/statistics.md), and it writes docs/comparison.md and the README only when asked
(`--write-docs`), not when run as the README writes it."""

from __future__ import annotations

import csv
import importlib.util
import json
import sys
from pathlib import Path

from tests.helpers import ROOT

TAKEOVER = {"alliance": [3.05, 3.10, 3.05], "murdoch": [2.30, 2.30, 2.30]}


def study():
    spec = importlib.util.spec_from_file_location(
        "compare_architectures", ROOT / "benchmarks" / "compare_architectures.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def results_of_an_earlier_study(out: Path) -> None:
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
        folder = out / f"patrol_{arch}"
        folder.mkdir(parents=True)
        with (folder / "results.csv").open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)


def docs(tmp_path: Path) -> tuple[Path, Path]:
    doc, readme = tmp_path / "comparison.md", tmp_path / "README.md"
    doc.write_text("intro\n<!-- table: begin -->\nold table\n<!-- table: end -->\nby hand\n")
    readme.write_text("top\n<!-- study: begin -->\nold headline\n<!-- study: end -->\n")
    return doc, readme


def test_the_study_writes_its_tables_into_its_output_only_unless_asked(tmp_path, capsys):
    out = tmp_path / "study"
    results_of_an_earlier_study(out)
    doc, readme = docs(tmp_path)
    before = doc.read_text(), readme.read_text()
    args = ["--reuse", "--output", str(out), "--missions", "patrol", "--faults", "none",
            "crash", "--seeds", "1", "2", "3", "--no-plots", "--doc", str(doc), "--readme",
            str(readme)]
    assert study().main(args) == 0
    assert (doc.read_text(), readme.read_text()) == before
    tables = (out / "tables.md").read_text()
    # the report's words and figures: ALLIANCE − MURDOCH paired by seed, Wilcoxon, A12
    assert "murdoch → alliance" in tables and "Holm family" in tables
    assert "2.30 (identical in every run)" in tables
    assert "| patrol | robot2@20 | takeover_seconds | 3.07 [" in tables
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    crash = next(x for x in lines if x.get("figure") == "takeover_seconds"
                 and x.get("pairs"))
    assert crash["pairs"] == 3 and abs(crash["alliance_minus_murdoch"] - 0.7667) < 1e-4
    assert lines[-1]["docs_rewritten"] == []

    assert study().main(args + ["--write-docs"]) == 0
    assert "murdoch → alliance" in doc.read_text() and "old table" not in doc.read_text()
    assert doc.read_text().endswith("<!-- table: end -->\nby hand\n")
    assert "| patrol | robot2@20 |" in readme.read_text()
