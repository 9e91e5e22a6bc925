"""`mrta experiment report` on hostile or huge results (issue 51.5): values that would overflow
its sums, a file past the size it reads whole, text that Markdown would read as markup, column
names that are no file names, an earlier report's pictures, and a two-level bootstrap whose
memory does not grow with a cell's size; and an experiment file's duplicate seeds found in one
pass."""

from __future__ import annotations

import re

import numpy as np
from click.testing import CliRunner

from mrta_supervisor.experiment import results, stats
from mrta_zenoh.cli.main import cli
from tests.test_report import report, rows, write


def one_line_exit_2(r) -> str:
    lines = r.output.strip().splitlines()
    assert r.exit_code == 2 and len(lines) == 1 and "Traceback" not in r.output, r.output
    return lines[0]


def test_a_value_that_would_overflow_the_sums_is_refused_naming_line_and_column(tmp_path):
    data = rows()
    data[3]["metrics.makespan"] = 1e308
    line = one_line_exit_2(report(write(tmp_path / "r", data)))
    assert re.search(r"results.csv:5: 'metrics.makespan': '1e\+308' is beyond ±1e\+15", line)


def test_a_results_file_past_the_cap_is_refused_in_one_line(tmp_path, monkeypatch):
    folder = write(tmp_path / "r", rows())
    monkeypatch.setattr(results, "MAX_RESULTS_BYTES", 1024)
    line = one_line_exit_2(report(folder))
    assert "results.csv: 0 MiB: a results.csv is read whole, at most 0 MiB" in line


def test_text_from_the_results_is_escaped_in_summary_md(tmp_path):
    data = rows()
    for r in data:
        r["failure"] = r["failure"] + "|<b>x</b>\n# Heading"
    folder = write(tmp_path / "r", data)
    assert report(folder, "--no-plots").exit_code == 0  # the text is summary.md's
    md = (folder / "summary.md").read_text()
    assert not any(line.startswith("# Heading") for line in md.splitlines())
    assert "<b>" not in md and r"\<b\>" in md
    overview = md.split("## Overview")[1].split("\n\n")[1].splitlines()
    width = overview[0].count("|")
    for line in overview[2:]:  # every row as many cells as the header: no pipe from the data
        assert len(re.findall(r"(?<!\\)\|", line)) == width, line


def test_column_names_become_safe_distinct_file_names_and_old_pictures_go(tmp_path):
    data = rows()
    for i, r in enumerate(data):  # n_robots: a team-size picture for every metric
        r["n_robots"] = 3
        r["metrics.a/../../b"] = float(i % 5 + 1)
        r["metrics.a_.._.._b"] = float(i % 3 + 1)
    folder = write(tmp_path / "r", data)
    # the pictures of the two hostile columns only (every metric's would show nothing more)
    two = report(folder, "--metrics", "metrics.a/../../b,metrics.a_.._.._b")
    assert two.exit_code == 0, two.output
    pictures = sorted(p.name for p in folder.glob("team_size_*.png"))
    assert not (folder / "team_size_metrics.a").exists() and not (tmp_path / "b.png").exists()
    assert "team_size_metrics.a_.._.._b.png" in pictures
    assert [p for p in pictures
            if re.fullmatch(r"team_size_metrics\.a_\.\._\.\._b-[0-9a-f]{8}\.png", p)]
    # a report of fewer metrics leaves no picture of the earlier one's beside its own
    assert report(folder, "--metrics", "metrics.makespan").exit_code == 0
    assert sorted(p.name for p in folder.glob("team_size_*.png")) == \
        ["team_size_metrics.makespan.png"]


def test_the_two_level_bootstrap_draws_in_bounded_blocks_with_the_same_numbers(monkeypatch):
    rng = np.random.default_rng(3)
    groups = [list(rng.normal(size=n)) for n in (4, 40, 9, 1)]
    whole = stats.bootstrap_two_level(groups, resamples=500)
    monkeypatch.setattr(stats, "BLOCK_CELLS", 37)  # one resample row at a time, or a few
    assert stats.bootstrap_two_level(groups, resamples=500) == whole


def test_a_seed_listed_twice_among_100000_is_named(tmp_path):
    f = tmp_path / "e.yaml"
    seeds = ", ".join(str(i) for i in range(100_000))
    f.write_text(f"application: patrol\nduration: 30\nseeds: [{seeds}, 99999]\n")
    r = CliRunner().invoke(cli, ["experiment", "run", str(f), "--output", str(tmp_path / "o")])
    line = one_line_exit_2(r)
    assert "'seeds/100000': seeds[100000]: 99999 is listed twice" in line
    assert not (tmp_path / "o").exists()
