"""The study shipped in docs/study/, reported: `python benchmarks/study_report.py [--write-docs]`.

docs/study/ holds the study's experiment files (`NN-<mission>-<size>-<fault>.yaml`, run in the
order of NN by `bash docs/study/run.sh`, cheapest complete cells first) and, beside each, the
folder its rows go to (`NN-…/results.csv`, committed as they come: docs/study/README.md). This
script runs nothing. It reads every folder's results.csv, puts the rows of one mission together
— delivery in the open room, delivery around walls, patrol — with each file's run numbers moved
to a block of their own (file NN's run r is NN · 100,000 + r, so every row stays one run of the
report), adds each objective's gap to its reference (compare_architectures.with_gaps), and
builds each mission's experiment report (mrta_supervisor.experiment.report_md.write_report:
cells.csv, comparisons.csv, summary.md) into OUTPUT/<mission>/. The tables are laid out from
those reports by study_tables (nothing here computes a statistic), under a table of what is in:
per size, fault and architecture, the runs that ended well against the file's matrix — a cell
short of its instances says so.

    python benchmarks/study_report.py --output /tmp/study-report             # into OUTPUT only
    python benchmarks/study_report.py --output /tmp/study-report --write-docs
        # also docs/comparison.md's <!-- table --> block, the README's <!-- study --> headline
        # and the plots docs/comparison.md shows (docs/img/study/)

tests/test_study_docs.py checks that docs/comparison.md's block is what this writes from the
committed rows.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mrta_zenoh.files import write_text  # noqa: E402
from mrta_supervisor.experiment.file import Experiment, load_experiment  # noqa: E402
from mrta_supervisor.experiment.provenance import revisions  # noqa: E402
from mrta_supervisor.experiment.report import Options, Report  # noqa: E402
from mrta_supervisor.experiment.report_md import write_report  # noqa: E402
from mrta_supervisor.experiment.results import read_results, write_csv  # noqa: E402

from compare_architectures import (DELIVERY_ARCHITECTURES, DELIVERY_METRICS,  # noqa: E402
                                   PATROL_METRICS, STUDY, TABLE, add_doc_options, exit_code,
                                   metrics_of, with_gaps, write_docs)
from study_tables import (delivery_tables, headline, mission_tables,  # noqa: E402
                          references_line, replace_block)

STUDY_DIR = ROOT / "docs" / "study"
RUN_BLOCK = 100_000  # file NN's run r is NN · RUN_BLOCK + r in a mission's combined rows
MISSIONS = ("delivery", "walls", "patrol")
STATUS = ("<!-- status: begin -->", "<!-- status: end -->")  # docs/study/README.md's block
BASELINES = {"delivery": "central", "walls": "central", "patrol": "murdoch"}


@dataclass(frozen=True)
class StudyFile:
    """One experiment file of the study and what its folder holds."""

    index: int            # NN: its place in the running order and its block of run numbers
    experiment: Experiment
    rows: list[dict[str, str]]

    @property
    def mission(self) -> str:
        spec = self.experiment.spec
        if spec.application != "delivery":
            return spec.application
        walls = spec.instances.parameters.get("walls", 0) if spec.instances else 0
        return "walls" if walls else "delivery"

    @property
    def per_cell(self) -> int:
        """Runs each cell of the file's matrix has when it is complete."""
        spec = self.experiment.spec
        instances = spec.instances.count if spec.instances is not None else 1
        return instances * len(spec.seeds)

    @property
    def complete(self) -> bool:
        """Every run of the file's matrix has its row: only then are its cells reported (a
        file in progress is a table of what is in, never a figure of the study's)."""
        return len(self.rows) >= self.per_cell * len(self.architectures)

    @property
    def architectures(self) -> list[str]:
        return [a for a in self.experiment.architectures if a is not None] or \
            [self.experiment.spec.architecture or ""]


def study_files(folder: Path) -> list[StudyFile]:
    """Every `NN-*.yaml` of the study in order, with the rows its folder holds (none yet: [])."""
    files = []
    for path in sorted(folder.glob("[0-9][0-9]-*.yaml")):
        results = path.with_suffix("") / "results.csv"
        rows = read_results(results).rows if results.is_file() else []
        files.append(StudyFile(int(path.name[:2]), load_experiment(path), rows))
    return files


def combined(files: list[StudyFile], mission: str, out: Path) -> Path | None:
    """The mission's rows of every complete file as one results.csv in OUT/<mission>/ (None:
    no file complete)."""
    rows = []
    for f in (f for f in files if f.mission == mission and f.complete):
        for r in f.rows:
            row = {**r, "run": f.index * RUN_BLOCK + int(r["run"])}
            rows.append(with_gaps(row) if mission != "patrol" else row)
    if not rows:
        return None
    (out / mission).mkdir(parents=True, exist_ok=True)
    write_csv(out / mission / "results.csv", rows, [])
    return out / mission / "results.csv"


def coverage(files: list[StudyFile], mission: str) -> list[str]:
    """What is in, per file: its size and fault, and each architecture's runs that ended well
    against what its matrix holds when complete; a file in progress is marked so, and the
    files with no row yet named in one line under the table."""
    mine = [f for f in files if f.mission == mission]
    archs = list(dict.fromkeys(a for f in mine for a in f.architectures))
    lines = ["| file | N / M | fault | " + " | ".join(archs) + " |",
             "| --- | --- | --- |" + " --- |" * len(archs)]
    for f in (f for f in mine if f.rows):
        spec = f.experiment.spec
        size = (f"{spec.instances.robots[0]} / {(spec.instances.tasks or ['N'])[0]}"
                if spec.instances is not None else "3 / 3")
        done = {a: sum(r.get("architecture") == a and r.get("status") == "ok" for r in f.rows)
                for a in f.architectures}
        name = f.experiment.file.stem + ("" if f.complete else " (in progress)")
        lines.append(f"| {name} | {size} | {', '.join(spec.failures)} | "
                     + " | ".join(f"{done[a]}/{f.per_cell}" if a in done else "n/a"
                                  for a in archs) + " |")
    waiting = [f.experiment.file.stem for f in mine if not f.rows]
    partial = [f.experiment.file.stem for f in mine if f.rows and not f.complete]
    return lines + ([] if not partial else
                    ["", f"In progress, not in the tables below until every run of the file "
                         f"has its row (each cell at its {mine[0].per_cell} instances): "
                         f"{', '.join(partial)}."]) + \
        ([] if not waiting else ["", f"Not run yet (no row): {', '.join(waiting)}."])


def code_of(rows: list[dict[str, str]]) -> str:
    """Which code made a file's rows (results.csv's `code`, provenance.py), each revision with
    its count; rows from before the column name none: "Which code made the rows" below."""
    return ", ".join(f"{k or 'before the column: see below'} ({n})"
                     for k, n in revisions(rows).items())


def status(files: list[StudyFile]) -> str:
    """docs/study/README.md's block: every file of the study, complete (in the tables), in
    progress (its rows committed, each architecture's instances counted, in no table) or not
    run yet — what a reader, or the next session resuming the study, needs first."""
    complete = [f for f in files if f.complete]
    partial = [f for f in files if f.rows and not f.complete]
    waiting = [f for f in files if not f.rows]
    lines = [f"**{len(complete)} of {len(files)} files complete** "
             f"({sum(len(f.rows) for f in complete):,} runs, every cell at all its instances: "
             "these alone are in docs/comparison.md's tables and the README headline); "
             f"{len(partial)} in progress; {len(waiting)} not run yet.", "",
             "| file | state | runs in / asked | ok | per architecture (instances or seeds in) "
             "| code (rows) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for f in (f for f in files if f.rows):
        asked = f.per_cell * len(f.architectures)
        ok = sum(r.get("status") == "ok" for r in f.rows)
        per = ", ".join(f"{a} {sum(r.get('architecture') == a for r in f.rows)}/{f.per_cell}"
                        for a in f.architectures)
        state = "complete" if f.complete else "**partial** (in no table)"
        lines.append(f"| {f.experiment.file.stem} | {state} | {len(f.rows)} / {asked} | "
                     f"{ok} | {per} | {code_of(f.rows)} |")
    if waiting:
        lines += ["", "Not run yet (no row): "
                  + ", ".join(f.experiment.file.stem[:2] for f in waiting) + "."]
    return "\n".join(lines)


def intro(report: Report, files: list[StudyFile], mission: str) -> str:
    """What the mission's rows are, in words: how many of the files' runs are in."""
    rows = report.table.rows
    failed = [r for r in rows if r.get("status") != "ok"]
    asked = sum(f.per_cell * len(f.architectures) for f in files if f.mission == mission)
    instances = len({r.get("instance") for r in rows})
    return (f"{len(rows):,} runs of the complete files, of the {asked:,} all its files ask "
            f"for, {len(failed)} not ok; {instances} distinct instances. Each cell: the mean "
            "and its 95 % bootstrap interval over instances (docs/statistics.md); a gap is the "
            "objective achieved over its reference − 1, in %; every cell reported has every "
            "instance of its file (a file in progress is only in the table of what is in, "
            "above). " + references_line(report))


def report_mission(files: list[StudyFile], mission: str, out: Path, plots: bool
                   ) -> Report | None:
    path = combined(files, mission, out)
    if path is None:
        return None
    wanted = PATROL_METRICS if mission == "patrol" else DELIVERY_METRICS
    archs = {r.get("architecture") for r in read_results(path).rows}
    return write_report(path, out / mission, Options(
        baseline=BASELINES[mission] if len(archs) > 1 else None,
        metrics=metrics_of(wanted, path), plots=plots))


def tables(folder: Path, out: Path, plots: bool = False) -> tuple[str, str, dict[str, Report]]:
    """(docs/comparison.md's block, the README's headline, each mission's report)."""
    files = study_files(folder)
    reports: dict[str, Report] = {}
    sections: list[str] = []
    for mission in MISSIONS:
        if not any(f.rows for f in files if f.mission == mission):
            continue
        title = {"walls": "delivery around walls"}.get(mission, mission)
        sections += [f"### {title}: what is in", ""] + coverage(files, mission) + [""]
        report = report_mission(files, mission, out, plots)
        if report is None:
            continue
        reports[mission] = report
        if mission == "patrol":
            sections += mission_tables(mission, out / mission) + [""]
        else:
            archs = [a for a in DELIVERY_ARCHITECTURES
                     if any(c.value("architecture") == a for c in report.cells)]
            sections += delivery_tables(report, archs, intro(report, files, mission),
                                        mission) + [""]
    runs = sum(len(r.table.rows) for r in reports.values())  # the complete files' runs
    short = headline(reports, list(DELIVERY_ARCHITECTURES), (
        f"The study in [docs/study/](docs/study/), its complete files ({runs:,} runs, every "
        "cell at all its instances; [docs/comparison.md](docs/comparison.md) says which files "
        "are in and which are in progress); generated "
        "delivery instances, every fault model, matched parameters, lockstep; mean and 95 % "
        "bootstrap interval over instances. Patrol: ALLIANCE and MURDOCH only."))
    return "\n".join(sections).rstrip(), "\n".join(short), reports


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--study", type=Path, default=STUDY_DIR, help="the study's folder")
    ap.add_argument("--output", type=Path, default=None, help="the reports (default: tmp)")
    add_doc_options(ap)
    args = ap.parse_args(argv)
    out = args.output or Path(tempfile.mkdtemp(prefix="mrta-study-report-"))
    table, short, reports = tables(args.study, out, plots=not args.no_plots)
    write_text(out / "tables.md", table + "\n\n" + short + "\n")
    if args.write_docs:
        write_docs(args, table, short, out, "delivery" in reports)
        replace_block(args.study / "README.md", STATUS, status(study_files(args.study)))
    print(out / "tables.md")
    return 0


if __name__ == "__main__":
    sys.exit(exit_code(main))
