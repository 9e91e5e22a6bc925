"""`mrta experiment`: a matrix of reproducible runs of an application, in parallel.

An experiment file (YAML, checked strictly: file, line and key on any error):

    application: patrol
    architecture: murdoch  # optional: the application under another architecture
    duration: 120          # simulated seconds per run
    seeds: [1, 2, 3, 4, 5]
    failures: [none, robot2@40, stall:robot2@40, "partition:robot2@40+10,loss:0.1"]
                           # each one fault spec (docs/delivery.md, "Fault grammar")
    overrides:             # optional sweeps: <parameter file glob>.<key path>: [values]
      robot*.timeout_duration: [2.0, 4.0]

Every combination × seed is one run: the application's mission (mission.py), run by
`mrta demo --application A [--architecture N] --duration D --speed 0 --fail F --seed S --output
DIR --no-live` as a child process (its own private rendezvous, lockstep at full speed). With overrides, the run gets its own copy of the
application package with the values changed, found first through MRTA_PACKAGE_PATH. The mission
writes `summary.json` (summary.py: who did what, coverage, failure and takeover, the
application's metrics) and `run.mcap`; this module gathers them into `results.csv` (one row per run, written as runs end,
so a Ctrl-C keeps the finished rows), `summary.md` (per configuration: mean and 95 % interval)
and plots (takeover time per configuration, coverage). A run that fails is a row with its error;
the others go on.

Where the runs go: on this machine, `jobs` at once (the default), or with `scheduler` as tasks
on a Dask cluster (experiment_dask.py, the optional `dask` extra). Both run the same argv
(`demo_args`) and turn what a run left into a row the same way (`row_for`, `error_of`), so the
same seeds give the same rows whichever ran them.
"""

from __future__ import annotations

import csv
import itertools
import logging
import math
import os
import shutil
import statistics
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mrta_zenoh.errors import ConfigError, Interrupted
from mrta_zenoh.failure import faults_problem, parse_faults
from mrta_zenoh.files import write_atomically, write_text
from mrta_zenoh.keys import normalize_robot_id
from mrta_zenoh.limits import MAX_RUNS, RUN_DURATION, SEED
from mrta_zenoh.processes import ProcessGroup, mrta_argv
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, load_yaml, plural

from .mission import MissionOptions, resolve
from .summary import COMPLETE, INCOMPLETE, flat_metrics, read_summary, run_problem

log = logging.getLogger("mrta.experiment")

KEYS = {"application", "architecture", "duration", "seeds", "robots", "failures", "overrides"}


@dataclass(frozen=True)
class Run:
    index: int
    seed: int
    failure: str
    overrides: tuple[tuple[str, Any], ...]

    @property
    def config(self) -> str:
        """Everything but the seed: runs of one configuration are compared together."""
        parts = [f"fail={self.failure}"] + [f"{k}={v}" for k, v in self.overrides]
        return " ".join(parts)


@dataclass
class Experiment:
    file: Path
    application: str
    duration: float
    seeds: list[int]
    failures: list[str]
    overrides: dict[str, list[Any]] = field(default_factory=dict)
    architecture: str | None = None
    doc: YamlDoc | None = field(default=None, compare=False, repr=False)  # for lines in errors

    def count(self) -> int:
        """How many runs `runs()` would make, without making them."""
        return len(self.failures) * math.prod(len(v) for v in self.overrides.values()) \
            * len(self.seeds)

    def check_runs(self, max_runs: int = MAX_RUNS) -> None:
        """Refuse a matrix of more than `max_runs` runs before anything starts: a list of a
        million seeds, or overrides whose product is a million, used to be accepted and
        started (issue #23)."""
        n = self.count()
        if n > max_runs:
            combos = math.prod(len(v) for v in self.overrides.values())
            raise ConfigError(
                f"this experiment makes {n:,} runs ({plural(len(self.failures), 'failure')} × "
                f"{combos:,} override combinations × {len(self.seeds):,} "
                f"{'seed' if len(self.seeds) == 1 else 'seeds'}), more than --max-runs "
                f"{max_runs:,}: pass --max-runs {n} to start them all", file=str(self.file))

    def check_against(self, robots: list[str]) -> None:
        """Every failure names one of the application's `robots` and happens before the end
        of a run; a ConfigError naming the line otherwise (before, a failure of an unknown
        robot was accepted and then failed every run the same way)."""
        for i, spec in enumerate(self.failures):
            if spec == "none":
                continue
            problem = faults_problem(parse_faults(spec), robots, self.duration)
            if problem:
                if self.doc is not None:
                    raise self.doc.error(("failures", i), f"failures[{i}]: {problem}")
                raise ConfigError(f"failures[{i}]: {problem}", file=str(self.file))

    def runs(self) -> list[Run]:
        keys = sorted(self.overrides)
        combos = list(itertools.product(*(self.overrides[k] for k in keys))) or [()]
        out = []
        for failure, combo, seed in itertools.product(self.failures, combos, self.seeds):
            out.append(Run(len(out), seed, failure, tuple(zip(keys, combo))))
        return out


def _list(doc: YamlDoc, key: str, kind, check=None) -> list:
    value = doc.data.get(key)
    if not isinstance(value, list) or not value:
        raise doc.error((key,), f"{key} must be a non-empty list")
    for i, v in enumerate(value):
        if type(v) is bool or not isinstance(v, kind):
            raise doc.error((key, i), f"{key}[{i}] must be {kind.__name__ if isinstance(kind, type) else 'a number'}, "
                                      f"got {v!r:.40}")
        if check is not None:
            problem = check(v)
            if problem:
                raise doc.error((key, i), f"{key}[{i}]: {problem}")
    return value


def _failure_problem(spec: str) -> str | None:
    if spec == "none":
        return None
    try:
        parse_faults(spec)
    except ValueError as exc:
        return f"{exc}, or none"
    return None


def load_experiment(path: Path) -> Experiment:
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "an experiment file must be a mapping")
    for k in doc.data:
        if k not in KEYS:
            raise doc.error((k,), f"unknown key {k!r}" + did_you_mean(k, KEYS))
    for k in ("application", "duration", "seeds"):
        if k not in doc.data:
            raise doc.error((), f"missing mandatory key {k!r}")
    app = doc.data["application"]
    if not isinstance(app, str) or not app:
        raise doc.error(("application",), "application must be a name")
    duration = doc.data["duration"]
    if RUN_DURATION.problem(duration):  # 1e308 is finite, and never ended
        raise doc.error(("duration",), f"duration (simulated seconds) "
                                       f"{RUN_DURATION.problem(duration)}")
    seeds = _list(doc, "seeds", int, SEED.problem)
    failures = [str(f) for f in _list(doc, "failures", str,
                                      _failure_problem)] \
        if "failures" in doc.data else ["none"]
    overrides: dict[str, list] = {}
    raw = doc.data.get("overrides") or {}
    if not isinstance(raw, dict):
        raise doc.error(("overrides",), "overrides must map PARAMETER_FILE_GLOB.KEY.PATH to lists")
    for key, values in raw.items():
        if not isinstance(key, str) or "." not in key:
            raise doc.error(("overrides", key), f"{key!r}: expected FILE_GLOB.KEY.PATH, e.g. "
                                                "robot*.timeout_duration")
        if not isinstance(values, list) or not values:
            raise doc.error(("overrides", key), f"{key}: expected a non-empty list of values")
        overrides[key] = values
    arch = doc.data.get("architecture")
    if arch is not None and (not isinstance(arch, str) or not arch):
        raise doc.error(("architecture",), "architecture must be a name (mrta arch list)")
    exp = Experiment(path, app, float(duration), seeds, failures, overrides, arch, doc)
    if "robots" in doc.data:
        _list(doc, "robots", int)
        exp.robots = doc.data["robots"]  # checked against the application in prepare()
    return exp


def _set_path(data: dict, path: list[str], value: Any, where: str) -> None:
    d = data
    for i, p in enumerate(path[:-1]):
        if not isinstance(d, dict) or p not in d:
            raise ConfigError(f"override {where}: no key {'.'.join(path[:i + 1])!r}")
        d = d[p]
    if not isinstance(d, dict) or path[-1] not in d:
        raise ConfigError(f"override {where}: no key {'.'.join(path)!r}")
    d[path[-1]] = value


def package_copy(pkg_path: Path, dest: Path, overrides: tuple[tuple[str, Any], ...]) -> Path:
    """A copy of the application's package with the overridden parameter values."""
    import fnmatch

    import yaml

    target = dest / pkg_path.name
    shutil.copytree(pkg_path, target, ignore=shutil.ignore_patterns("__pycache__", "*.py"))
    for key, value in overrides:
        glob, _, dotted = key.partition(".")
        files = [f for f in sorted((target / "config").glob("*.yaml"))
                 if fnmatch.fnmatch(f.stem, glob) or fnmatch.fnmatch(f.stem, glob + "_*")]
        if not files:
            raise ConfigError(f"override {key}: no parameter file matches {glob!r}")
        for f in files:
            data = yaml.safe_load(f.read_text())
            _set_path(data, dotted.split("."), value, f"{key} in {f.name}")
            f.write_text(yaml.safe_dump(data, sort_keys=False))
    return target


def mean_ci(xs: list[float], confidence: float = 0.95) -> tuple[float, float]:
    """Mean and the half-width of its `confidence` interval: Student's t with n − 1 degrees of
    freedom, its quantile exact (scipy), not a table's (the old table used 2.0 for 10–29
    degrees of freedom: intervals up to 10 % too narrow)."""
    if not xs:
        return math.nan, math.nan
    m = statistics.fmean(xs)
    if len(xs) < 2:
        return m, math.nan
    from scipy.stats import t as student_t  # scipy only where statistics are made

    q = float(student_t.ppf(0.5 + confidence / 2, len(xs) - 1))
    return m, q * statistics.stdev(xs) / math.sqrt(len(xs))


def paired_difference(rows: list[dict], key: str, config: str, baseline: str
                      ) -> tuple[float, float, int]:
    """Mean difference of `key` between two configurations over the seeds both ran
    successfully (config − baseline, paired by seed: the same seed is the same world and the
    same random streams), its 95 % half-width, and the number of pairs."""
    def by_seed(c: str) -> dict:
        return {r["seed"]: float(r[key]) for r in rows if r["config"] == c
                and r["status"] == "ok" and r.get(key) not in ("", None)}
    a, b = by_seed(config), by_seed(baseline)
    diffs = [a[s] - b[s] for s in sorted(a.keys() & b.keys())]
    m, h = mean_ci(diffs)
    return m, h, len(diffs)


def demo_args(package: str, duration: float, run: Run, out: Path) -> list[str]:
    """`mrta ARGS…` for one run, whichever backend starts it (here, or a Dask worker): one
    spelling, so both run exactly the same mission."""
    return ["-q", "demo", "--application", package, "--duration", str(duration), "--speed",
            "0", "--fail", run.failure, "--seed", str(run.seed), "--output", str(out),
            "--no-live"]


def start_run(group: ProcessGroup, package, duration: float, run: Run, out: Path):
    """One run's mission as a child of `group`, writing into `out` (which exists): with its own
    copy of the application package when the run overrides parameters. The one way both
    backends start a run (here, and on a Dask worker)."""
    env = {}
    if run.overrides:
        package_copy(package.path, out / "package", run.overrides)
        env["MRTA_PACKAGE_PATH"] = str(out / "package")
    return group.start(mrta_argv(*demo_args(package.name, duration, run, out)),
                       name=f"run{run.index:03d}", env=env, merge_stderr=True)


def error_of(returncode: int, lines: list[str]) -> str:
    """The `error` cell of a run that did not exit 0: its code, the mission's own error line
    (which names the process that failed and its exit code) and the end of its output."""
    said = next((line for line in reversed(lines) if line.startswith("Error:")), "")
    tail = " | ".join(line for line in lines[-5:] if line.strip() and line != said)
    return (f"exit {returncode}: " + " | ".join(filter(None, [said, tail])))[-600:]


def row_for(run: Run, out: Path, wall: float, error: str = "") -> dict:
    row: dict[str, Any] = {"run": run.index, "config": run.config, "seed": run.seed,
                           "failure": run.failure, "status": "failed" if error else "ok",
                           "error": error, "wall_seconds": round(wall, 2)}
    row.update({k: v for k, v in run.overrides})
    if error:
        return row
    summary = read_summary(out / "summary.json")
    if summary.lockstep_exact is False:
        row["status"] = "inexact"
        row["error"] = run_problem(summary) + (" (fewer --jobs)" if summary.run_status == COMPLETE
                                               else "")
    row.update(flat_metrics(summary))
    # counted by the run's own analysis (mission.message_rates), not by reading run.mcap again
    row["messages"] = "" if summary.messages.total is None else summary.messages.total
    return row


def prepare_output(output: Path) -> None:
    """The output folder, made (with its parents) before any run starts, or a ConfigError
    naming it: `--output /proc/self/x` was a traceback."""
    try:
        output.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--output: cannot make the folder: {exc.strerror}",
                          file=str(output)) from None
    if not os.access(output, os.W_OK | os.X_OK):
        raise ConfigError("--output: the folder is not writable", file=str(output))


def check_overrides(exp: Experiment, pkg_path: Path, arch, robots: list[str]) -> None:
    """Every overridden value, alone, through the architecture's own check of a robot's files
    (Architecture.check_files: what its agent reads at start): an absurd value is refused with
    the experiment file's line before the first run starts — not by every run that uses it,
    in a generated copy of the package."""
    if not exp.overrides:
        return
    stem = arch.param_stem
    with tempfile.TemporaryDirectory(prefix="mrta-overrides-") as tmp:
        for n, (key, value) in enumerate((k, v) for k in sorted(exp.overrides)
                                         for v in exp.overrides[k]):
            try:
                cfg = package_copy(pkg_path, Path(tmp) / str(n), ((key, value),)) / "config"
                layers = cfg / f"layers_{stem}_params.yaml"
                for rid in robots:
                    arch.check_files(rid, cfg / f"{rid}_{stem}_params.yaml",
                                     cfg / f"tasks_{stem}_params.yaml",
                                     layers if layers.is_file() else None)
            except ConfigError as exc:
                what = f"{exc.element}: {exc.detail}" if exc.element else exc.detail
                message = f"override {key} = {value!r}: {what}"
                if exp.doc is not None:
                    raise exp.doc.error(("overrides", key), message) from None
                raise ConfigError(message, file=str(exp.file)) from None


def run_experiment(*, file: Path, output: Path, jobs: int | None = None,
                   stop: threading.Event | None = None, progress=None,
                   scheduler: str | None = None, max_runs: int = MAX_RUNS) -> list[dict]:
    """Every run of FILE's matrix, `jobs` at once here or, with `scheduler` (a Dask scheduler's
    address), as tasks on that cluster; returns the rows (also in OUTPUT/results.csv).
    A matrix of more than `max_runs` runs is refused before anything starts."""
    if scheduler is not None:
        from . import experiment_dask  # stdlib and mrta only: `distributed` is imported lazily

        if jobs is not None:
            raise ConfigError("--jobs is for runs on this machine; with --scheduler the "
                              "workers' `runs` resources say how many run at once")
        experiment_dask.check_address(scheduler)
        experiment_dask.require_distributed()  # before anything is written
    exp = load_experiment(file)
    exp.check_runs(max_runs)
    reg = Registry()
    resolved = resolve(MissionOptions(application=exp.application,
                                      architecture=exp.architecture), reg)
    pkg, app = resolved.package, resolved.app
    if getattr(exp, "robots", None) and exp.robots != [len(app.robots)]:
        raise ConfigError(f"robots: the application {app.name!r} has {len(app.robots)} robots "
                          f"(its launch file starts them); got {exp.robots}", file=str(file))
    robots = [normalize_robot_id(r.id) for r in app.robots]
    exp.check_against(robots)
    check_overrides(exp, pkg.path, resolved.arch, robots)
    runs = exp.runs()
    prepare_output(output)
    stop = stop or threading.Event()
    results = Results(output / "results.csv", len(runs), progress)
    if scheduler is not None:
        experiment_dask.run_on_cluster(scheduler, package=pkg, duration=exp.duration, runs=runs,
                                       output=output, stop=stop, results=results)
    else:
        _run_here(pkg, exp.duration, runs, output, max(1, jobs or os.cpu_count() or 1), stop,
                  results)
    rows = results.finish()
    write_text(output / "summary.md", summary_md(exp, rows))
    plot_results(rows, output)
    if stop.is_set():
        raise Interrupted(f"stopped after {len(rows)} of {plural(len(runs), 'run')}; {results.path} has "
                          "them")
    return rows


class Results:
    """The rows of the runs that ended, in results.csv as soon as each ends (a Ctrl-C or a
    crash keeps them), the progress callback told."""

    def __init__(self, path: Path, total: int, progress=None):
        self.path, self.total, self.progress = path, total, progress
        self.rows: list[dict] = []
        self.fields: list[str] = []

    def add(self, run: Run, out: Path, wall: float, error: str = "") -> dict:
        row = row_for(run, out, wall, error)
        self.rows.append(row)
        self.fields = _write_csv(self.path, self.rows, self.fields)
        if self.progress is not None:
            self.progress(len(self.rows), self.total, row)
        return row

    def finish(self) -> list[dict]:
        """The rows in run order, results.csv rewritten in that order."""
        self.rows.sort(key=lambda r: r["run"])
        _write_csv(self.path, self.rows, [])
        return self.rows


def inexact(out: Path) -> bool:
    """Whether the run in `out` wrote a summary that is not exact, or not complete (`mrta demo`
    then exits 1): summary.json's lockstep_exact and run_status."""
    try:
        summary = read_summary(out / "summary.json")
    except ConfigError:
        return False
    return summary.lockstep_exact is False or summary.run_status == INCOMPLETE


def _run_here(pkg, duration: float, runs: list[Run], output: Path, jobs: int,
              stop: threading.Event, results: Results) -> None:
    """The runs as child processes of this one, `jobs` at once. A run whose lockstep was not
    exact is run again, once, before its row is written (here; on a Dask cluster the row is
    marked, not run again): its figures depended on the
    machine; if it is inexact again, its row says so (status `inexact`) and the statistics
    leave it out, like a failed run."""
    pending = list(runs)
    retried: set[int] = set()
    active: dict[int, tuple[Run, Any, float, Path]] = {}
    with ProcessGroup() as group:
        while (pending or active) and not stop.is_set():
            while pending and len(active) < jobs:
                run = pending.pop(0)
                out = output / f"run{run.index:03d}"
                if out.exists():
                    shutil.rmtree(out)
                out.mkdir(parents=True)
                child = start_run(group, pkg, duration, run, out)
                active[run.index] = (run, child, time.monotonic(), out)
            for run in _collect(active, results, retried):
                retried.add(run.index)
                pending.insert(0, run)
            stop.wait(0.1)
        if stop.is_set():
            # a run that ended cleanly before the stop is a finished run: keep its row; the
            # others are stopped and left out, so the files describe exactly what finished
            _collect(active, results, only_clean=True)
            group.stop_all()


def _collect(active: dict, results: Results, retried: set[int] | None = None,
             only_clean: bool = False) -> list[Run]:
    """Rows for the runs of `active` whose process has ended (with `only_clean`: ended with
    exit 0), written to results.csv at once; returns the runs to run again instead (inexact
    lockstep, not yet in `retried`)."""
    again = []
    for index, (run, child, t0, out) in list(active.items()):
        if child.running() or (only_clean and child.returncode != 0):
            continue
        del active[index]
        rc = child.wait(10)
        if retried is not None and index not in retried and inexact(out):
            again.append(run)
            continue
        results.add(run, out, time.monotonic() - t0, "" if rc == 0 else error_of(rc, child.stdout))
    return again


def _write_csv(path: Path, rows: list[dict], fields: list[str]) -> list[str]:
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


def _fmt(m: float, h: float, unit: str = "") -> str:
    if math.isnan(m):
        return "–"
    return f"{m:.2f}{unit}" + ("" if math.isnan(h) else f" ± {h:.2f}")


def summary_md(exp: Experiment, rows: list[dict]) -> str:
    """Per configuration, over the runs that finished: mean and 95 % interval of the takeover,
    the coverage per task and every numeric metric the application measured (`metrics.*`
    columns); then each configuration against the first, paired by seed. Describes exactly
    the rows given (after a Ctrl-C: the runs that finished)."""
    configs = sorted({r["config"] for r in rows})
    tasks = sorted({k.split(".")[0] for r in rows for k in r if k.endswith(".exactly_one")})
    metrics = sorted({k for r in rows for k, v in r.items() if k.startswith("metrics.")
                      and isinstance(v, (int, float)) and not isinstance(v, bool)})
    seeds = sorted({r["seed"] for r in rows})
    arch = f" under {exp.architecture}" if exp.architecture else ""
    lines = [f"# {exp.application}{arch}: {plural(len(rows), 'run')} of {exp.duration:g} s", "",
             "Mean ± half-width of the 95 % interval (Student's t) over seeds "
             f"({', '.join(map(str, seeds))}). Coverage: share of the run with exactly one "
             "robot on the task.", "",
             "| configuration | runs (failed) | takeover (s) | "
             + " | ".join(f"{t} covered" for t in tasks)
             + "".join(f" | {m.removeprefix('metrics.')}" for m in metrics) + " |",
             "| --- | --- | --- | " + " | ".join("---" for _ in tasks)
             + " | ---" * len(metrics) + " |"]
    for c in configs:
        rs = [r for r in rows if r["config"] == c]
        ok = [r for r in rs if r["status"] == "ok"]
        take = mean_ci([float(r["takeover_seconds"]) for r in ok
                        if r.get("takeover_seconds") not in ("", None)])
        cov = [mean_ci([float(r[f"{t}.exactly_one"]) for r in ok if f"{t}.exactly_one" in r])
               for t in tasks]
        app = [mean_ci([float(r[m]) for r in ok if r.get(m) not in ("", None)]) for m in metrics]
        lines.append(f"| {c} | {len(rs)} ({len(rs) - len(ok)}) | {_fmt(*take)} | "
                     + " | ".join(_fmt(m * 100, h * 100, " %") if not math.isnan(m) else "–"
                                  for m, h in cov)
                     + "".join(f" | {_fmt(*v)}" for v in app) + " |")
    if len(configs) > 1:
        base = configs[0]
        keys = ["takeover_seconds"] + [f"{t}.exactly_one" for t in tasks] + metrics
        lines += ["", f"Paired differences against `{base}` (same seeds; mean ± 95 % "
                      "half-width; n = pairs):", "",
                  "| configuration | " + " | ".join(keys) + " |",
                  "| --- |" + " --- |" * len(keys)]
        for c in configs[1:]:
            cells = []
            for k in keys:
                m, h, n = paired_difference(rows, k, c, base)
                cells.append("–" if n == 0 else f"{_fmt(m, h)} (n = {n})")
            lines.append(f"| {c} | " + " | ".join(cells) + " |")
    failed = [r for r in rows if r["status"] != "ok"]
    if failed:
        lines += ["", "Failed runs:", ""] + [f"- run {r['run']} ({r['config']}, seed "
                                             f"{r['seed']}): {r['error']}" for r in failed]
    return "\n".join(lines) + "\n"


def plot_results(rows: list[dict], output: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mrta_zenoh.files import save_figure

    configs = sorted({r["config"] for r in rows})
    data = [[float(r["takeover_seconds"]) for r in rows if r["config"] == c
             and r["status"] == "ok" and r.get("takeover_seconds") not in ("", None)]
            for c in configs]
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(configs)), 4), dpi=100)
    try:
        shown = [(c, d) for c, d in zip(configs, data) if d]
        if shown:
            ax.boxplot([d for _, d in shown])
            ax.set_xticks(range(1, len(shown) + 1), [c for c, _ in shown])
        ax.set_ylabel("takeover time (s)")
        ax.set_title("takeover after a failure, per configuration")
        ax.tick_params(axis="x", labelsize=7, rotation=15)
        fig.tight_layout()
        save_figure(fig, output / "takeover.png")
    finally:
        plt.close(fig)
    tasks = sorted({k.split(".")[0] for r in rows for k in r if k.endswith(".exactly_one")})
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(configs)), 4), dpi=100)
    try:
        width = 0.8 / max(1, len(tasks))
        for i, t in enumerate(tasks):
            means = [mean_ci([float(r[f"{t}.exactly_one"]) for r in rows if r["config"] == c
                              and r["status"] == "ok" and f"{t}.exactly_one" in r])[0]
                     for c in configs]
            ax.bar([j + i * width for j in range(len(configs))],
                   [0 if math.isnan(m) else m for m in means], width, label=t)
        ax.set_xticks([j + width * (len(tasks) - 1) / 2 for j in range(len(configs))])
        ax.set_xticklabels(configs, fontsize=7, rotation=15)
        ax.set_ylabel("share with exactly one robot")
        ax.set_ylim(0, 1.05)
        ax.legend(fontsize=8)
        fig.tight_layout()
        save_figure(fig, output / "coverage.png")
    finally:
        plt.close(fig)
