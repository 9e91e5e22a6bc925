"""`results.csv`: one row per run of an experiment, written as runs end and read back, strictly,
by the report (report.py) — the report is made from this file alone.

A row holds the run's bookkeeping (`run`, `config`, `seed`, `status`, `error`,
`wall_seconds`, `code` — which code made it, provenance.py —, `taken_over_by`, `failed_robot` — the robot its fault struck, which a fault
naming a role, `@first` or `@random`, resolves per run), every parameter that defines its cell
(`mission`, `application`, `architecture`, `duration`, `instance`, `n_robots`, `n_tasks` — the
last three with an `instances:` block — `failure`, one column per parameter override), and
what the run measured (summary.flat_metrics: the takeover, coverage per task — not for runs of
instances, whose task ids are their own — traffic and its coordination kinds' `messages.*`,
what injected faults did to those messages (`faults.lost`, `.delayed`, `.cut_off`,
`.out_of_range`), when the run ended, the decisions and their computation time, the application's `metrics.*`).
Which column is which is decided by name alone (`kind`), so a file from another
version, or rows of several experiments put together, read the same way: a measured column is
one of the framework's own or ends in a coverage share or starts with `metrics.`,
`messages.` or `faults.`; bookkeeping
is the fixed list; every other column is a parameter. An override whose key would read as a
measure is refused by the experiment file (file.py), so the split is exact.
"""

from __future__ import annotations

import csv
import io
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_atomically
from mrta_zenoh.yamlfile import did_you_mean

log = logging.getLogger("mrta.experiment")

# `agents_per_process`: how the run's agents were hosted, which changes no result (agent hosts)
# `code`: which code made the row (provenance.py), blank in rows made before it was recorded
BOOKKEEPING = ("run", "config", "seed", "status", "error", "wall_seconds", "taken_over_by",
               "failed_robot", "agents_per_process", "code")
MEASURES = ("takeover_seconds", "first_full_allocation", "messages", "messages_per_second",
            "coordination_messages_per_second", "namespace_messages_per_second", "ended_at",
            "decisions", "decision_ms_median", "decision_ms_max")
COVERAGE = (".exactly_one", ".none", ".more_than_one")
APPLICATION_PREFIX = "metrics."
MESSAGES_PREFIX = "messages."  # coordination messages of each kind (summary.flat_metrics)
FAULTS_PREFIX = "faults."  # what injected faults did to them, by cause (mission/fault_effects.py)
# what the machine, not the run, decides: two runs of one seed differ in these alone — wall
# and computing time, and the whole bus's counts, whose edges (the recording's first and last
# messages) fall where the machine's timing puts them (a message more or less in ~2700)
MACHINE_TIME = ("wall_seconds", "decision_ms_median", "decision_ms_max", "messages",
                "messages_per_second", "namespace_messages_per_second")
INSTANCE, SEED, STATUS, OK = "instance", "seed", "status", "ok"
REQUIRED = (SEED, STATUS)
# Bounds (issue 51.5): a measure of 1e308 overflowed the report's sums (OverflowError), and a
# results.csv is read whole — past these, one line naming the file (and line and column)
MAX_MEASURE = 1e15
MAX_RESULTS_BYTES = 64 * 2**20


def kind(column: str) -> str:
    """"bookkeeping", "measure" or "parameter" (see the module's docstring)."""
    if column in BOOKKEEPING:
        return "bookkeeping"
    if column in MEASURES or column.endswith(COVERAGE) \
            or column.startswith((APPLICATION_PREFIX, MESSAGES_PREFIX, FAULTS_PREFIX)):
        return "measure"
    return "parameter"


# the names the report's tables print for the framework's measures (`title`)
TITLES = {"takeover_seconds": "takeover (s)", "first_full_allocation": "first full allocation (s)",
          "coordination_messages_per_second": "coordination msgs/s",
          "messages_per_second": "all msgs/s", "namespace_messages_per_second": "namespace msgs/s"}
COVERED = " covered"  # `wander covered`: the share of a run with exactly one robot on wander


def title(metric: str) -> str:
    """A column's name in a table's header (its section heading names the column too)."""
    if metric in TITLES:
        return TITLES[metric]
    if metric.endswith(".exactly_one"):
        return metric.removesuffix(".exactly_one") + COVERED
    return metric.removeprefix(APPLICATION_PREFIX)


def column_named(name: str, columns: list[str] | None = None) -> str:
    """The results.csv column a metric's name stands for: the column's own name, or the name the
    report's tables print for it (`title`: `makespan` for `metrics.makespan`, `takeover (s)`,
    `wander covered`); with `columns` (a file's), the one among them. Without, a bare name
    that is no framework measure, nor close to one, is the application's `metrics.NAME`. The
    name as given when it stands for nothing (the caller refuses it, with a did-you-mean)."""
    reverse = {v: k for k, v in TITLES.items()}
    candidates = [name, reverse.get(name, name)]
    if name.endswith(COVERED):
        candidates.append(name.removesuffix(COVERED) + ".exactly_one")
    if columns is not None:
        return next((c for c in candidates + [APPLICATION_PREFIX + name] if c in columns), name)
    known = next((c for c in candidates if kind(c) == "measure"), None)
    if known is not None:
        return known
    if name.strip() and "." not in name and not did_you_mean(name, MEASURES):
        return APPLICATION_PREFIX + name
    return name


def measure_problem(key: str) -> str | None:
    """Why an override key would be read back as a measure (None: it would not)."""
    if kind(key) != "parameter":
        return (f"{key!r} would read as a measured column of results.csv (a name ending in "
                f"{', '.join(COVERAGE)} or starting with {APPLICATION_PREFIX!r}, "
                f"{MESSAGES_PREFIX!r} or {FAULTS_PREFIX!r}, or a "
                "framework column)")
    return None


@dataclass
class ResultsTable:
    """The rows of a results.csv (values as written: strings), and where each came from."""

    path: Path
    columns: list[str]
    rows: list[dict[str, str]]
    lines: list[int]  # the file line of each row, for errors

    @property
    def parameters(self) -> list[str]:
        return [c for c in self.columns if kind(c) == "parameter"]

    def ok(self) -> list[dict[str, str]]:
        return [r for r in self.rows if r.get(STATUS) == OK]

    def number(self, row: dict[str, str], column: str) -> float | None:
        """The value of `column` in `row` as a number, None when blank; ConfigError naming the
        file, its line and the column when it is something else."""
        text = row.get(column, "")
        if text is None or text.strip() == "":
            return None
        try:
            value = float(text)
        except ValueError:
            raise self.error(row, column, f"not a number: {text!r:.40}") from None
        if not math.isfinite(value):
            raise self.error(row, column, f"not a finite number: {text!r:.40}")
        if abs(value) > MAX_MEASURE:
            raise self.error(row, column, f"{text!r:.40} is beyond ±{MAX_MEASURE:g}, no run's "
                                          "figure (sums of such values overflow)")
        return value

    def error(self, row: dict[str, str] | None, column: str, message: str) -> ConfigError:
        line = self.lines[self.rows.index(row)] if row is not None else 1
        return ConfigError(message, file=str(self.path), line=line, element=f"'{column}'")

    def check_metric(self, column: str) -> None:
        """A metric named by the user is a measured column of this file."""
        measures = [c for c in self.columns if kind(c) == "measure"]
        if column not in self.columns:
            raise ConfigError(f"no column {column!r}" + did_you_mean(column, measures)
                              + f"; measured columns: {', '.join(measures) or 'none'}",
                              file=str(self.path), line=1)
        if kind(column) != "measure":
            raise ConfigError(f"{column!r} is a {kind(column)} column, not a measured one"
                              + did_you_mean(column, measures), file=str(self.path), line=1)


def read_results(path: Path, torn: bool = False) -> ResultsTable:
    """results.csv, checked: the columns every report needs (`seed`, `status`), seeds as
    integers, no row longer than the header. Measures are checked as they are read
    (ResultsTable.number). With `torn` (a folder being resumed), a last line without its
    newline, or a last row shorter than the header, is a row cut off mid-write: left out."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_RESULTS_BYTES:
            raise ConfigError(f"{size / 2**20:.0f} MiB: a results.csv is read whole, at most "
                              f"{MAX_RESULTS_BYTES // 2**20} MiB (≈ 100,000 runs)",
                              file=str(path))
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot read the results: {exc.strerror}", file=str(path)) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"not a CSV file: {exc}", file=str(path)) from None
    cut = torn and bool(text) and not text.endswith("\n")
    if cut:
        text = text[:text.rfind("\n") + 1]
    try:
        reader = csv.reader(io.StringIO(text, newline=""))
        header = next(reader, None)
        if not header:
            raise ConfigError("empty: no header row", file=str(path))
        rows, lines = [], []
        for cells in reader:
            if not cells:
                continue
            if len(cells) > len(header):
                raise ConfigError(f"{len(cells)} cells for {len(header)} columns",
                                  file=str(path), line=reader.line_num)
            rows.append(dict(zip(header, cells + [""] * (len(header) - len(cells)))))
            lines.append(reader.line_num)
            short = len(cells) < len(header)
    except csv.Error as exc:
        raise ConfigError(f"not a CSV file: {exc}", file=str(path)) from None
    if torn and rows and short:
        cut = True
        rows.pop()
        lines.pop()
    if cut:
        log.warning("%s: its last line was cut off mid-write; that run runs again", path)
    table = ResultsTable(path, header, rows, lines)
    for column in REQUIRED:
        if column not in header:
            raise ConfigError(f"missing column {column!r}" + did_you_mean(column, header),
                              file=str(path), line=1, element=f"'{column}'")
    for row in rows:
        try:
            int(row[SEED])
        except ValueError:
            raise table.error(row, SEED, f"not an integer: {row[SEED]!r:.40}") from None
    return table


def write_csv(path: Path, rows: list[dict[str, Any]], fields: list[str]) -> list[str]:
    """`rows` to `path`, whole or not at all, under `fields` extended by every key a row has."""
    for r in rows:
        for k in r:
            if k not in fields:
                fields.append(k)

    def write(tmp: Path) -> None:
        with tmp.open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=fields)
            w.writeheader()
            for r in rows:
                w.writerow(r)

    write_atomically(path, write)
    return fields
