"""What an experiment's output folder already holds: resuming an interrupted run of the same
file, shards of one matrix, and refusing a folder that holds another experiment.

A study does not fit one sitting: `mrta experiment FILE --output DIR` on a folder that holds an
interrupted run of the same file runs only the runs results.csv has no row for, so the rows of
the finished folder are those of an uninterrupted run (but for the machine's own columns,
results.MACHINE_TIME). Resuming reads nothing but results.csv — the run folders are optional —
so a study can continue on another machine from committed rows.

The folder's identity is `experiment.json`: the file it was made from, the sha256 digest of
its resolved matrix (`matrix_digest`: every run's number, cell, seed and instance, with the
instance file's own bytes — not the file's text, so a comment or a move changes nothing,
while another seed list, fault or generator output does) and the shard. A file whose digest
differs is refused before anything is written (exit 2). A folder without experiment.json but
with rows (results.csv alone committed, or a folder from an older version) is checked row by
row: every row must be the run of this matrix its number says.

A last line without its newline is a row torn by a copy or a crash mid-write (results.csv is
itself written whole, files.write_atomically, but a folder may have been copied or synced while
being written): it is dropped, and its run is run again.

Shards (`--shard I/N`): the runs whose number is I-1 modulo N, in any backend — every N-th run
from the I-th, so each shard gets a share of every cell and the shards of one matrix are
disjoint and cover it. Each shard's folder records its shard; `mrta experiment report DIR…`
(`merge_folders`) puts the folders of one file's shards (or of any disjoint parts) together.
"""

from __future__ import annotations

import hashlib
import json
import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_text

from .file import Experiment, Run
from .runs import prepare_output
from .results import ResultsTable, read_results, write_csv

log = logging.getLogger("mrta.experiment")

IDENTITY = "experiment.json"
RESULTS = "results.csv"
_SHARD = re.compile(r"^(\d+)/(\d+)$")


class Identity(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """experiment.json: which matrix a folder's rows are runs of."""

    file: str            # the experiment file's name, for messages (not part of the identity)
    digest: str          # matrix_digest of the file's matrix
    runs: int            # runs in the file's matrix (without --until-ci's blocks)
    shard: str | None = None  # "I/N" when the folder holds one shard


@dataclass(frozen=True)
class Shard:
    """`--shard I/N`: the I-th of N (1-based)."""

    index: int
    count: int

    def takes(self, run: int) -> bool:
        return run % self.count == self.index - 1

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"


def parse_shard(text: str) -> Shard:
    """`I/N` with 1 ≤ I ≤ N; a ConfigError saying what is expected otherwise."""
    m = _SHARD.match(text.strip())
    if not m or not 1 <= int(m[1]) <= int(m[2]):
        raise ConfigError(f"--shard {text!r}: expected I/N, the I-th of N shards with "
                          "1 ≤ I ≤ N (e.g. 1/4)")
    return Shard(int(m[1]), int(m[2]))


# ------------------------------------------------------------------ identity
def run_key(run: Run) -> dict[str, str]:
    """What a row of results.csv must say to be the row of `run`, as results.csv writes it."""
    return {"run": str(run.index), "config": run.config, "seed": str(run.seed),
            "instance": run.instance.name if run.instance is not None else ""}


def matrix_digest(exp: Experiment, runs: list[Run]) -> str:
    """sha256 over everything that defines the rows of `runs`: the application, architecture and
    duration, and each run's number, cell, seed, overrides and instance (its file's bytes)."""
    files: dict[Path, str] = {}

    def instance(run: Run) -> list[str] | None:
        if run.instance is None:
            return None
        path = run.instance.path
        if path not in files:
            files[path] = hashlib.sha256(path.read_bytes()).hexdigest()
        return [run.instance.name, files[path]]

    doc = {"application": exp.spec.application, "architecture": exp.spec.architecture,
           "duration": exp.spec.duration,
           "runs": [[r.index, r.config, r.seed, r.failure, r.architecture,
                     [[k, v] for k, v in r.overrides], instance(r)] for r in runs]}
    text = json.dumps(doc, sort_keys=True, default=repr, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def identity_of(exp: Experiment, runs: list[Run], shard: Shard | None) -> Identity:
    return Identity(file=exp.file.name, digest=matrix_digest(exp, runs), runs=len(runs),
                    shard=None if shard is None else str(shard))


def read_identity(folder: Path) -> Identity | None:
    """The folder's experiment.json (None: it has none); a ConfigError naming it when it is no
    identity."""
    path = folder / IDENTITY
    if not path.is_file():
        return None
    try:
        return msgspec.json.decode(path.read_bytes(), type=Identity)
    except (msgspec.DecodeError, msgspec.ValidationError) as exc:
        raise ConfigError(f"not an experiment identity: {exc}", file=str(path)) from None


def write_identity(folder: Path, identity: Identity) -> None:
    write_text(folder / IDENTITY,
               msgspec.json.format(msgspec.json.encode(identity), indent=2).decode() + "\n")


def check_folder(folder: Path, identity: Identity) -> None:
    """Refuse a folder that holds the runs of another matrix, or another shard of this one,
    before anything is written (the caller writes experiment.json once this passes)."""
    old = read_identity(folder)
    if old is None:
        return
    if old.digest != identity.digest:
        raise ConfigError(f"--output {folder} holds the runs of another experiment "
                          f"({old.file}, {old.runs} runs; this file makes {identity.runs}): "
                          "give another --output, or the same file to resume it")
    if old.shard != identity.shard:
        raise ConfigError(f"--output {folder} holds {_shard_text(old.shard)} of this "
                          f"experiment, not {_shard_text(identity.shard)}: give the same "
                          "--shard to resume it, or another --output")


def _shard_text(shard: str | None) -> str:
    return "every run" if shard is None else f"shard {shard}"


# ------------------------------------------------------------------ rows already there
def done_rows(folder: Path, runs: list[Run], total: int) -> list[dict[str, str]]:
    """The rows results.csv already holds for this matrix of `total` runs (`runs`: the ones
    this folder is for, its shard's), each checked to be the run its number says; rows past the
    matrix are --until-ci's blocks, checked when their block is made (`check_block`). A torn
    last line is dropped."""
    path = folder / RESULTS
    if not path.is_file() or not path.read_bytes().strip():
        return []  # also the blank file an experiment stopped before its first row once left
    table = read_results(path, torn=True)
    if "run" not in table.columns or "config" not in table.columns:
        raise ConfigError("results.csv without the run and config columns cannot be resumed",
                          file=str(path), line=1)
    by_index = {r.index: r for r in runs}
    seen: dict[int, int] = {}
    for row, line in zip(table.rows, table.lines):
        index = _index(table, row)
        if index in seen:
            raise table.error(row, "run", f"run {index} has two rows (lines {seen[index]} and "
                                          f"{line}): keep one")
        seen[index] = line
        if index in by_index:
            _check_row(table, row, by_index[index])
        elif index < total:
            raise table.error(row, "run", f"run {index} is not one of this folder's runs "
                                          "(another shard's?)")
    return table.rows


def _index(table: ResultsTable, row: dict[str, str]) -> int:
    try:
        return int(row["run"])
    except ValueError:
        raise table.error(row, "run", f"not a run number: {row['run']!r:.40}") from None


def _check_row(table: ResultsTable, row: dict[str, str], run: Run) -> None:
    want = run_key(run)
    got = {k: row.get(k, "") for k in want}
    if got != want:
        differ = ", ".join(f"{k} {got[k]!r} (the file's: {want[k]!r})" for k in want
                           if got[k] != want[k])
        raise table.error(row, "run", f"run {run.index} is not this experiment's: {differ}; "
                                      "give another --output")


def check_block(rows: dict[int, dict[str, Any]], runs: list[Run]) -> list[Run]:
    """The runs of an --until-ci block that have no row yet; a ConfigError when a row of the
    block is another run (an earlier --block)."""
    missing = []
    for run in runs:
        row = rows.get(run.index)
        if row is None:
            missing.append(run)
            continue
        want = run_key(run)
        if {k: str(row.get(k, "")) for k in want} != want:
            raise ConfigError(f"results.csv's run {run.index} is seed {row.get('seed')} of "
                              f"{row.get('config')}, not seed {run.seed} of {run.config}: "
                              "resume with the --block of the interrupted run")
    return missing


# ------------------------------------------------------------------ several folders as one
def merge_folders(folders: list[Path], output: Path) -> Path:
    """The rows of several folders of one experiment (its shards, or any disjoint parts) as one
    results.csv in OUTPUT, with the identity of the whole matrix (so `mrta experiment FILE
    --output OUTPUT` resumes it: runs no shard ran). Refused, naming them: a folder without
    experiment.json (nothing says which matrix its rows are of), folders of different files,
    a run with rows in two folders, OUTPUT among the folders."""
    if output.resolve() in {f.resolve() for f in folders}:
        raise ConfigError(f"--output {output} is one of the folders reported: give another "
                          "folder for the merged report")
    identities = []
    for folder in folders:
        identity = read_identity(folder)
        if identity is None:
            raise ConfigError(f"{folder} has no {IDENTITY}: nothing says which experiment its "
                              "rows are of (run it with this version, or report it alone)")
        identities.append(identity)
    first = identities[0]
    for folder, identity in zip(folders[1:], identities[1:]):
        if identity.digest != first.digest:
            raise ConfigError(f"{folders[0]} and {folder} hold different experiments "
                              f"({first.file}, {first.runs} runs; {identity.file}, "
                              f"{identity.runs} runs): report each alone")
    rows: list[dict[str, str]] = []
    fields: list[str] = []
    where: dict[int, tuple[Path, int]] = {}
    for folder in folders:
        table = read_results(folder / RESULTS)
        for row, line in zip(table.rows, table.lines):
            index = _index(table, row)
            if index in where:
                other, at = where[index]
                raise table.error(row, "run", f"run {index} (seed {row['seed']}, "
                                              f"{row.get('config', '')}) is also in "
                                              f"{other / RESULTS}:{at}: report each once")
            where[index] = (folder, line)
            rows.append(row)
        fields += [c for c in table.columns if c not in fields]
    rows.sort(key=lambda r: int(r["run"]))
    prepare_output(output)
    write_csv(output / RESULTS, rows, fields)
    write_identity(output, Identity(file=first.file, digest=first.digest, runs=first.runs))
    return output / RESULTS
