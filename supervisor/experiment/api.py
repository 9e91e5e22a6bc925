"""`mrta experiment`: a matrix of reproducible runs of an application, in parallel, and its
report.

The experiment file (file.py) gives the matrix: every cell (a failure × parameter
overrides) × seed is one run — the application's mission (mrta_supervisor.mission), run as `mrta demo …
--speed 0 --no-live` in a child process (runs.py: its own private rendezvous,
lockstep at full speed; with overrides, its own copy of the application package). Runs go on
this machine, `jobs` at once, or with `scheduler` as tasks on a Dask cluster
(dask_backend.py); both run the same argv and make the same rows, so the same seeds give the
same rows whichever ran them. Each row lands in `results.csv` as its run ends (a Ctrl-C keeps
the finished rows); a run that fails is a row with its error and the others go on. Runs start
pairs first (`paired_first`: every cell's run of the first instance and seed, then the next),
so an interrupted matrix holds whole pairs; their numbers do not change. At the end
the report is made from results.csv alone (report_md.write_report: summary.md, cells.csv,
comparisons.csv, plots), as `mrta experiment report` makes it.

Pictures: a run draws its own (world, timeline, the architecture's plots: 7.8 s of CPU for a
20 s patrol run, 41 % of the run's; benchmarks/experiment_plots.py) only when it is the first
run of its cell — one set per cell shows what the cell does; every run keeps its recording,
from which `mrta plot` draws any other. `plots=False` draws none, the report's included.

Run until precise (`until`: metric → half-width): after the file's seeds, blocks of `block`
new seeds (the next integers above those used) — or, when the file has an instance generator,
`block` new instances of every size (two-level bootstrap: only instances narrow an interval
over instances) — are added to every cell until the bootstrap
half-width of each named metric is below the target in every cell, or the next block would
pass `max_runs`. Every cell gets every block, so architectures and configurations stay paired
seed for seed; the blocks depend only on the results, so the same command gives the same rows,
here or on Dask. A cell where a metric has no value in any run (a takeover where nothing fails)
has nothing to narrow and holds no block up.
"""

from __future__ import annotations

import logging
import os
import shutil
import tempfile
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh import forkserver
from mrta_zenoh.errors import ConfigError, Interrupted
from mrta_zenoh.instances import kinds as instance_kinds
from mrta_zenoh.limits import MAX_RUNS, SEED
from mrta_zenoh.processes import ProcessGroup
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.yamlfile import did_you_mean, plural

from . import dask_backend, slurm_backend
from .file import (Experiment, Run, _failure_problem, load_experiment)  # noqa: F401
from .runs import (Context, Results, bytecode_cache, error_of, inexact, package_copy,
                   prepare_output, start_run)
from .instances import place as place_instances, prepare as prepare_instances
from .resume import (Shard, check_block, check_folder, done_rows, identity_of,
                     write_identity)
from ..mission.hook import MissionOptions, MissionRun, resolve
from .report import Options, build
from .report_md import Precision, write_report
from .results import APPLICATION_PREFIX, COVERAGE, MEASURES, column_named, kind, read_results

log = logging.getLogger("mrta.experiment")


def parse_target(text: str) -> tuple[str, float]:
    """`METRIC:HALF_WIDTH` of --until-ci; a ConfigError saying what is expected otherwise. The
    metric is a measured column of results.csv (results.kind), by its name or the one the
    report's tables print (results.column_named: `makespan`): refused here, before any run,
    when it cannot be one."""
    metric, sep, width = text.rpartition(":")
    try:
        half = float(width)
    except ValueError:
        half = float("nan")
    if not sep or not metric or not half > 0 or half == float("inf"):
        raise ConfigError(f"--until-ci {text!r}: expected METRIC:HALF_WIDTH, a results.csv "
                          "column and a number > 0 (e.g. takeover_seconds:0.1)")
    metric = column_named(metric)
    if kind(metric) != "measure":
        known = list(MEASURES) + ["TASK" + s for s in COVERAGE] + ["metrics.NAME"]
        raise ConfigError(f"--until-ci {text!r}: {metric!r} is not a measured column"
                          + did_you_mean(metric, MEASURES) + f"; measured: {', '.join(known)}")
    return metric, half


def check_targets(until: dict[str, float] | None, exp: Experiment,
                  resolved: dict[str | None, MissionRun]) -> None:
    """Every --until-ci metric is one these runs measure, refused before any run (and by
    --dry-run) otherwise — not after the file's whole matrix ran, when the first block's
    report finds no such column: an application metric must be one the mission compares (its
    `better`: the metrics the report judges), coverage (`TASK.exactly_one`) a task of the
    application in runs that record it (not runs of instances, whose task ids are their own),
    and `first_full_allocation` a mission whose tasks are held at once."""
    if not until:
        return
    run = next(iter(resolved.values()))
    mission = run.mission
    for metric in until:
        problem = None
        if metric.startswith(APPLICATION_PREFIX):
            name = metric.removeprefix(APPLICATION_PREFIX)
            if name not in mission.better:
                known = sorted(mission.better)
                problem = (f"the {mission.name} mission measures no {name!r}"
                           + did_you_mean(name, known) + "; its metrics: "
                           + (", ".join(known) or "none"))
        elif metric.endswith(COVERAGE):
            task = metric.rsplit(".", 1)[0]
            tasks = {t for r in resolved.values() for t in r.app.tasks()}
            if exp.spec.instances is not None:
                problem = ("runs of instances record no coverage per task (each instance's "
                           "task ids are its own)")
            elif task not in tasks:
                problem = (f"the application has no task {task!r}"
                           + did_you_mean(task, sorted(tasks)))
        elif metric == "first_full_allocation" and not mission.instantaneous:
            problem = (f"the {mission.name} mission's tasks are served in turn: its runs "
                       "record no first_full_allocation")
        if problem is not None:
            raise ConfigError(f"--until-ci {metric}: {problem}")


def check_overrides(exp: Experiment, pkg_path: Path, arch, robots: list[str]) -> None:
    """Every overridden value, alone, through the architecture's own check of a robot's files
    (Architecture.check_files: what its agent reads at start): an absurd value is refused with
    the experiment file's line before the first run starts."""
    overrides = exp.spec.overrides or {}
    if not overrides:
        return
    stem = arch.param_stem
    with tempfile.TemporaryDirectory(prefix="mrta-overrides-") as tmp:
        for n, (key, value) in enumerate((k, v) for k in sorted(overrides)
                                         for v in overrides[k]):
            try:
                cfg = package_copy(pkg_path, Path(tmp) / str(n), ((key, value),)) / "config"
                layers = cfg / f"layers_{stem}_params.yaml"
                for rid in robots:
                    arch.check_files(rid, cfg / f"{rid}_{stem}_params.yaml",
                                     cfg / f"tasks_{stem}_params.yaml",
                                     layers if layers.is_file() else None)
            except ConfigError as exc:
                what = f"{exc.element}: {exc.detail}" if exc.element else exc.detail
                under = f" under {arch.name}" if exp.spec.architectures else ""
                raise exp.error(("overrides", key),
                                f"override {key} = {value!r}{under}: {what}") from None


def resolve_all(exp: Experiment) -> dict[str | None, MissionRun]:
    """The application package, mission and architecture of every value of the architecture
    axis (None: the file's one), each refused at its line when nothing runs the application
    under it."""
    out = {}
    for i, name in enumerate(exp.architectures):
        options = MissionOptions(application=exp.spec.application,
                                 architecture=name if name is not None
                                 else exp.spec.architecture)
        try:
            out[name] = resolve(options, Registry())
        except ConfigError as exc:
            if name is None:
                raise
            raise exp.error(("architectures", i), f"architectures[{i}]: {exc.detail}") from None
    return out


def prepare_experiment(exp: Experiment, output: Path, shard: Shard | None = None,
                       dry: bool = False, until: dict[str, float] | None = None
                       ) -> tuple[Experiment, dict, list[dict]]:
    """Everything checked before the first run, then the instances made into OUTPUT: the
    experiment with its instances, the run set-up of each architecture, and the rows OUTPUT's
    results.csv already holds (a resumed run: resume.py). The instances are made in a
    staging folder first, so a folder holding another experiment is refused with nothing
    written. `dry`: everything checked, nothing written (the instances returned are the
    staged ones, gone with the call: count them, do not run them)."""
    resolved = resolve_all(exp)
    check_targets(until, exp, resolved)
    first = next(iter(resolved.values()))
    mission = first.mission.name
    if exp.spec.instances is not None and mission not in instance_kinds():
        raise exp.error(("instances",), f"instances: the {mission!r} mission reads no "
                        "instance files (applications that do: "
                        f"{', '.join(sorted(instance_kinds())) or 'none'})")
    if exp.spec.instances is None:
        exp.check_team(len(first.app.robots), first.app.name)
    with tempfile.TemporaryDirectory(prefix="mrta-staging-") as staging:
        if exp.spec.instances is not None:
            exp = exp.with_instances(prepare_instances(exp.spec.instances, mission,
                                                       exp.file.parent, Path(staging), exp.doc))
        with tempfile.TemporaryDirectory(prefix="mrta-derived-") as tmp:
            for run in resolved.values():
                robots = [r.id for r in run.app.robots]
                exp.check_against(robots, tuple(run.arch.processes))
                check_overrides(exp, *_overridden(exp, run, Path(tmp), robots))
        runs = exp.runs()
        identity = identity_of(exp, runs, shard)
        check_folder(output, identity)
        done = done_rows(output, runs if shard is None else
                         [r for r in runs if shard.takes(r.index)], len(runs))
        if dry:
            return exp, resolved, done
        prepare_output(output)
        if exp.instances:
            exp = exp.with_instances(place_instances(exp.instances, output))
        write_identity(output, identity)
    return exp, resolved, done


def _overridden(exp: Experiment, run: MissionRun, tmp: Path, robots: list[str]):
    """The package the overrides of `run`'s architecture are checked against, with its robots:
    the installed one, or — with instances, whose runs set them in the packages each derives
    (mission/overrides.py) — the first instance's, derived into `tmp`."""
    if not exp.spec.overrides or not exp.instances:
        return run.package.path, run.arch, robots
    inst = exp.instances[0]
    folder = tmp / run.arch.name
    run.mission.derive(inst.path, folder)
    path = Registry([folder]).find(run.package.name).path
    if folder.resolve() not in Path(path).resolve().parents:  # found the installed one
        raise exp.error(("overrides",), f"overrides: instance {inst.name} derives no "
                        f"{run.package.name!r} package to set them in")
    return path, run.arch, list(inst.robots)


def dry_run(file: Path, output: Path, shard: Shard | None = None,
            max_runs: int = MAX_RUNS, until: dict[str, float] | None = None) -> str:
    """`mrta experiment run FILE --dry-run`: FILE checked as a run would check it before its
    first run — its fields, the architectures, overrides and fault specs against each team,
    every instance generated and read back as the application reads it — and what a run
    would do, in words: the matrix, its instances, what OUTPUT already holds. Nothing runs
    and nothing is written (a study's 58 files are checked so: docs/study/README.md)."""
    exp = load_experiment(file)
    exp.check_runs(max_runs)
    exp, resolved, done = prepare_experiment(exp, output, shard, dry=True, until=until)
    runs = exp.runs() if shard is None else [r for r in exp.runs() if shard.takes(r.index)]
    teams = sorted({(i.n_robots, i.n_tasks) for i in exp.instances})
    what = (f"{plural(len(exp.instances), 'instance')} ("
            + ", ".join(f"{n} robots × {m} tasks" for n, m in teams) + ")") \
        if exp.instances else "the application's own instance"
    return (f"{file}: {plural(len(runs), 'run')}{f' (shard {shard})' if shard else ''} — "
            f"{plural(len(exp.cells()), 'cell')} × {what} × "
            f"{plural(len(exp.spec.seeds), 'seed')}; {len(done)} already in {output}, "
            f"{len(runs) - len(done)} to run; architectures: "
            f"{', '.join(str(a or r.arch.name) for a, r in resolved.items())}; checked, "
            "nothing run or written")


def run_experiment(*, file: Path, output: Path, jobs: int | None = None,
                   stop: threading.Event | None = None, progress=None,
                   scheduler: str | None = None, max_runs: int = MAX_RUNS,
                   until: dict[str, float] | None = None, block: int = 1, plots: bool = True,
                   report: Options = Options(), shard: Shard | None = None,
                   slurm: slurm_backend.SlurmOptions | None = None,
                   agents_per_process: int | None = None, warm: bool = True) -> list[dict]:
    """Every run of FILE's matrix (and, with `until`, the blocks of seeds it takes), `jobs` at
    once here or, with `scheduler` (a Dask scheduler's address), as tasks on that cluster;
    or, with `slurm`, as SLURM array tasks (slurm_backend.py);
    returns the rows (also in OUTPUT/results.csv) and writes the report beside them. A matrix
    of more than `max_runs` runs is refused before anything starts. Runs OUTPUT's results.csv
    already has a row for are not run again (resuming: resume.py); with `shard`, only
    that shard's runs are this call's. `agents_per_process`: the file's `agents_per_process:`
    replaced (its rows are the same either way: agent hosts). `warm`: runs here are forked by
    a fork server that imported their modules once (mrta_zenoh.forkserver: the same rows, less
    CPU), not started as fresh interpreters."""
    if scheduler is not None:
        if jobs is not None:
            raise ConfigError("--jobs is for runs on this machine; with --scheduler the "
                              "workers' `runs` resources say how many run at once")
        dask_backend.check_address(scheduler)
        dask_backend.require_distributed()  # before anything is written
    if slurm is not None:
        if jobs is not None or scheduler is not None:
            raise ConfigError("--backend slurm runs every run as an array task: --jobs (this "
                              "machine) and --scheduler (Dask) are for the other backends")
        slurm.check(output)
    if shard is not None and until:
        raise ConfigError(f"--until-ci with --shard {shard}: the blocks depend on every row of "
                          "the matrix; run --until-ci on the shards' folders reported together "
                          "(mrta experiment report DIR… --output OUT), then resume OUT")
    exp = load_experiment(file)
    if agents_per_process is not None:
        exp = replace(exp, spec=msgspec.structs.replace(exp.spec,
                                                        agents_per_process=agents_per_process))
    exp.check_runs(max_runs)
    exp, resolved, done = prepare_experiment(exp, output, shard, until=until)
    stop = stop or threading.Event()
    runs = exp.runs()
    pictures = {next(r.index for r in runs if r.cell == c) for c in exp.cells()} if plots \
        else set()
    mine = runs if shard is None else [r for r in runs if shard.takes(r.index)]
    # the application as the file names it, not the package configured for the architecture
    # (patrol_murdoch): runs of one application under two architectures are of one instance
    first = next(iter(resolved.values()))
    context = Context(first.mission.name, exp.spec.application,
                      "" if exp.spec.architectures else first.arch.name, exp.spec.duration)
    results = Results(output / "results.csv", len(mine), progress, context, done)
    if done:
        log.info("resuming: %s of %s already in %s", len(done), plural(len(mine), "run"),
                 results.path)
    packages = {name: run.package for name, run in resolved.items()}
    backend = _Backend(packages, exp.spec.duration, output, jobs, scheduler, stop, results,
                       pictures, slurm, warm)
    have = results.done()
    backend.run(paired_first(exp, [r for r in mine if r.index not in have]))
    precision = None
    if until:
        precision = _until_precise(exp, backend, runs, until, block, max_runs, report)
    rows = results.finish()
    if rows:  # a Ctrl-C before any run ended leaves nothing to report
        options = replace(report, plots=plots, metrics=_with_targets(report.metrics, until))
        write_report(output / "results.csv", output, options, precision)
    if stop.is_set():
        raise Interrupted(f"stopped after {len(rows)} of {plural(results.total, 'run')}; "
                          f"{results.path} has them: the same command resumes")
    return rows


def paired_first(exp: Experiment, runs: list[Run]) -> list[Run]:
    """The order runs are started in (their numbers, and so results.csv, are unchanged): the
    first instance and seed in every cell, then the next — so a matrix interrupted part-way (a
    study that takes several sittings) holds whole pairs of every architecture and failure on
    the instances it reached, rather than all of one cell and nothing of the next."""
    rank = {i.name: n for size in exp.sizes() if size is not None
            for n, i in enumerate(j for j in exp.instances if j.size == size)}
    seeds = {s: n for n, s in enumerate(exp.spec.seeds)}
    return sorted(runs, key=lambda r: (rank.get(r.instance.name, 0) if r.instance else 0,
                                       seeds.get(r.seed, len(seeds) + r.seed), r.index))


def _with_targets(metrics: tuple[str, ...] | None, until: dict[str, float] | None):
    if metrics is None or not until:
        return metrics
    return tuple(metrics) + tuple(m for m in until if m not in metrics)


def _until_precise(exp: Experiment, backend: "_Backend", runs: list[Run],
                   until: dict[str, float], block: int, max_runs: int,
                   report: Options) -> Precision:
    """Blocks of new instances (a file with an instance generator) or new seeds for every cell
    until every cell is precise enough (module docstring); the precision reached, for
    summary.md."""
    more_of = _instance_blocks(exp, backend.output, block, backend.results.context.mission) \
        if _generated(exp) else _seed_blocks(exp, block)
    total, blocks = len(runs), 1
    missed: list[tuple[str, str, float | None]] = []
    while not backend.stop.is_set():
        backend.results.finish()  # results.csv in run order: the report reads it
        missed = missed_targets(backend.results.path, until, report)
        if not missed:
            break
        more = more_of(total, blocks - 1)
        if more is None or total + len(more) > max_runs:
            break
        log.info("block %d: %s for %s", blocks + 1, plural(len(more), "run"),
                 ", ".join(f"{c} {m}" for c, m, _ in missed[:3]))
        backend.results.expect(total + len(more))
        backend.run(check_block(backend.results.done(), more))
        total += len(more)
        blocks += 1
    return Precision(until, total, max_runs, blocks, missed, backend.stop.is_set(),
                     by=f"{plural(block, 'new instance')} of every size"
                     if _generated(exp) else f"{plural(block, 'new seed')} in every cell")


def _generated(exp: Experiment) -> bool:
    return exp.spec.instances is not None and exp.spec.instances.generator is not None


def _seed_blocks(exp: Experiment, block: int):
    """Block k's runs: every cell and instance × the k-th `block` seeds above the file's."""
    top = max(exp.spec.seeds)

    def more(first: int, k: int) -> list[Run]:
        return exp.runs(list(range(top + 1 + k * block, top + 1 + (k + 1) * block)), first)
    return more


def _instance_blocks(exp: Experiment, output: Path, block: int, mission: str):
    """Block k's runs: `block` new instances of every size — the generator's next seeds after
    the file's own (seed + count + k·block …), made into OUTPUT/instances — × every cell of
    their size × the file's seeds. With a two-level bootstrap over instances, more seeds of the
    same instances cannot narrow an interval whose width comes from the instances. None when
    the next seeds are past the generator seed's range."""
    spec = exp.spec.instances
    state = {"exp": exp}

    def more(first: int, k: int) -> list[Run] | None:
        start = spec.seed + spec.count + k * block
        if SEED.problem(start + block - 1):
            return None
        current = state["exp"]
        new = prepare_instances(spec, mission, exp.file.parent, output, current.doc,
                                range(start, start + block))
        state["exp"] = current.with_instances(current.instances + new)
        return state["exp"].runs(first=first, instances=new)
    return more


def missed_targets(results: Path, until: dict[str, float], report: Options = Options()
                   ) -> list[tuple[str, str, float | None]]:
    """(cell, metric, half-width) of every cell whose bootstrap half-width of a targeted
    metric is not below its target (None: fewer than two values, no interval yet). A cell
    without any value of the metric is left out: there is nothing to narrow."""
    table = read_results(results)
    rep = build(table, replace(report, metrics=tuple(until), plots=False))
    missed = []
    for f in rep.figures:
        d, target = f.figures, until[f.metric]
        if d.n == 0:
            continue
        half = 0.0 if d.identical else (d.interval.half_width if d.interval else None)
        if half is None or not half < target:
            missed.append((f.cell.label, f.metric, half))
    return missed


class _Backend:
    """Where runs go: this machine (`jobs` at once), a Dask cluster or SLURM array tasks; each
    run's row is added to `results` as it ends. `packages`: the application package of each
    architecture."""

    def __init__(self, packages: dict, duration: float, output: Path, jobs: int | None,
                 scheduler: str | None, stop: threading.Event, results: Results,
                 pictures: set[int], slurm: slurm_backend.SlurmOptions | None = None,
                 warm: bool = True):
        self.packages, self.duration, self.output = packages, duration, output
        self.warm = warm
        self.jobs = max(1, jobs or os.cpu_count() or 1)
        self.scheduler, self.stop, self.results, self.pictures = scheduler, stop, results, pictures
        self.slurm = slurm

    def run(self, runs: list[Run]) -> None:
        if self.stop.is_set() or not runs:
            return
        if self.slurm is not None:
            slurm_backend.run_on_slurm(packages=self.packages, duration=self.duration,
                                       runs=runs, output=self.output, stop=self.stop,
                                       results=self.results, pictures=self.pictures,
                                       options=self.slurm, warm=self.warm)
        elif self.scheduler is not None:
            dask_backend.run_on_cluster(self.scheduler, packages=self.packages,
                                        duration=self.duration, runs=runs,
                                        output=self.output, stop=self.stop,
                                        results=self.results, pictures=self.pictures,
                                        warm=self.warm)
        else:
            _run_here(self.packages, self.duration, runs, self.output, self.jobs, self.stop,
                      self.results, self.pictures, self.warm)


def _run_here(packages: dict, duration: float, runs: list[Run], output: Path, jobs: int,
              stop: threading.Event, results: Results, pictures: set[int] = frozenset(),
              warm: bool = True) -> None:
    """The runs as child processes of this one, `jobs` at once. A run whose lockstep was not
    exact is run again, once, before its row is written (here; on a Dask cluster the row is
    marked, not run again): its figures depended on the machine; if it is inexact again, its
    row says so (status `inexact`) and the statistics leave it out, like a failed run.
    `warm`: the runs' processes are forked by a fork server (runs.warm_modules)."""
    pending = list(runs)
    retried: set[int] = set()
    active: dict[int, tuple[Run, Any, float, Path]] = {}
    with bytecode_cache() as env, ProcessGroup({**os.environ, **env}) as group:
        while (pending or active) and not stop.is_set():
            while pending and len(active) < jobs:
                run = pending.pop(0)
                out = output / f"run{run.index:03d}"
                if out.exists():
                    shutil.rmtree(out)
                out.mkdir(parents=True)
                child = start_run(group, packages[run.architecture], duration, run, out,
                                  run.index in pictures, warm=warm)
                active[run.index] = (run, child, time.monotonic(), out)
            running = len(active)
            for run in _collect(active, results, retried):
                retried.add(run.index)
                pending.insert(0, run)
            if len(active) == running:  # nothing ended: look again soon (else start the next now)
                stop.wait(0.1)
        if stop.is_set():
            # a run that ended cleanly before the stop is a finished run: keep its row; the
            # others are stopped and left out, so the files describe exactly what finished
            _collect(active, results, only_clean=True)
        forkserver.finish(group)


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
