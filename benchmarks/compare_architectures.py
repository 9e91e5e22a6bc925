"""The architecture study: `python benchmarks/compare_architectures.py --output DIR`.

Delivery over generated instances — team sizes and task counts crossed (`--robots`,
`--tasks-per-robot`: M = N and M = 2N), `--instances` instances of each size from the
experiment's `instances:` block (docs/statistics.md, "Instances") — under every registered
delivery architecture (alliance, murdoch, central, ssi, cbba) and every fault model, each spec
named by role or channel so one spec fits every team (`--fault-at` T = 5 s, docs/delivery.md,
"Fault grammar"):

    none        no fault
    crash       crash:@first@T          the robot first to hold a task dies at T
    stall       stall:@first@T          it stays alive and talking, but stops moving
    partition   partition:@first@T+10   it neither hears nor is heard for 10 s, then rejoins
    loss        loss:0.2                each coordination message lost for each receiver, 20 %
    latency     latency:0.5+-0.2        each coordination message heard 0.5 ± 0.2 s late
    range       range:4                 messages between robots over 4 m apart dropped (a third
                                        of the 12 m × 8 m room: most pairs start out of range)
    dispatcher  crash:dispatcher@T      central's dispatcher dies at T (docs/central.md)

The dispatcher crash applies to central only: the other architectures have no dispatcher, and
their cells of that fault are "n/a" in the tables — never a faultless copy under its name.
Larger teams (`--large-robots`, e.g. 10) join delivery's report with fewer instances and
faults (`--large-instances`, `--large-faults`): a 10-robot run costs 2–3 times a 5-robot one.
Mission `walls`: delivery on instances with `--walls` walls the robots drive around (costs on a
visibility graph), its own sizes, count and faults (`--walls-*`), its own section. One
`mrta experiment` per mission × architecture, lockstep at full speed (a run's outcome depends
on its instance and seed only), `--jobs` at once here or `--scheduler ADDRESS` on a Dask
cluster; runs draw no pictures (the study reads none; `plots=False`).

Patrol stays ALLIANCE against MURDOCH: its tasks never end (wander, border protection, report),
while central, SSI and CBBA plan routes over point tasks for a time-extended objective — there is
no route to plan over a task that is never done. Its two architectures run with matched
parameters (experiment overrides; the shipped packages are not touched):

    ALLIANCE  broadcast_rate 2 Hz, timeout_duration τ = 2 s
    MURDOCH   renewal_period 0.5 s (2 Hz), lease_timeout 2 s

Delivery is matched the same way (overrides set in each run's derived packages,
supervisor/mission/overrides.py), pinned to the values below so a change of the generator's defaults
cannot unmatch the study:

    ALLIANCE  broadcast_rate 2 Hz, timeout_duration τ = 2 s
    MURDOCH   renewal_period 0.5 s, lease_timeout 2 s
    central   robots report every 1 s; the dispatcher's progress_timeout 10 s (stall watch)
    SSI, CBBA robots report every 1 s; progress_timeout 10 s (stall watch)

Not matched, and why: MURDOCH's per-task progress_timeout (60 s) is a contract deadline — a
task not done within it is revoked — not a watch on motion: 10 s would revoke every healthy
contract longer than that (a delivery here takes 10–50 s). ALLIANCE's watch is its patience φ,
the holder's expected duration of the task (2 × (travel + service) + 10 s, per task): a stalled
robot keeps broadcasting, and teammates' impatience turns fast only once φ has run out — that is
the architecture, and the study measures it.

Every delivery objective stands beside its reference value (metrics.reference_<objective>, the
instance's exact optimum up to 10 tasks, else OR-Tools' best found; `reference_proven_optimal`
says which): the combined results.csv gains `metrics.gap_<objective>` — achieved ÷ reference − 1,
in % — and `metrics.reference_objective_<objective>`, the reference under the name the report
pairs with `metrics.objective_<objective>` (its performance profile against the reference).

The tables are the experiment report's (mrta_supervisor.experiment.report_md, docs/statistics.md): all
architectures' rows of a mission go into OUTPUT/<mission>/results.csv, and the report made from
it — per cell the mean with its bootstrap interval over instances, runs missing a figure counted
apart; each architecture against `--baseline` paired by instance and seed, Wilcoxon p
Holm-adjusted, A12, the probability of improvement; performance profiles against the best
architecture and against the reference; each metric against the team size — is
OUTPUT/<mission>/summary.md, cells.csv, comparisons.csv and its plots. OUTPUT/tables.md holds the
study's tables and the README's headline; one JSON line per figure goes to stdout.

It writes nothing outside OUTPUT unless asked: `--write-docs` rewrites the block between
`<!-- table: begin -->` and `<!-- table: end -->` of docs/comparison.md (the discussion around
it is written by hand), the README's `<!-- study: begin -->` … `<!-- study: end -->` headline,
and copies the plots the page shows into docs/img/study/.

    python benchmarks/compare_architectures.py --output /tmp/study --jobs 2   # defaults
    --robots 5 --tasks-per-robot 1 2 --instances 2 --large-robots 10   # sizes and counts
    --scheduler tcp://127.0.0.1:8786   # on a Dask cluster (workers: --resources runs=1)
    --reuse --output /tmp/study --write-docs   # what OUTPUT holds is not run again

Runs of one instance share its reference values ($MRTA_REFERENCE_CACHE, set by the runner
beside the instance files; give Dask workers one folder of their own): the references of a
10 × 20 instance cost more than its mission.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from mrta_zenoh.architectures import architecture_names  # noqa: E402
from mrta_zenoh.errors import ConfigError, MrtaRuntimeError  # noqa: E402
from mrta_zenoh.files import write_atomically, write_text  # noqa: E402
from mrta_supervisor.experiment.api import run_experiment  # noqa: E402
from mrta_supervisor.experiment.report import Options, Report  # noqa: E402
from mrta_supervisor.experiment.report_md import write_report  # noqa: E402
from mrta_supervisor.experiment.results import read_results, write_csv  # noqa: E402

from study_tables import (delivery_tables, headline, json_lines, mission_tables,  # noqa: E402
                          references_line, replace_block, size_of)

DELIVERY_ARCHITECTURES = ("alliance", "murdoch", "central", "ssi", "cbba")
PATROL_ARCHITECTURES = ("alliance", "murdoch")  # continuous tasks: no routes to plan
ROUTE_MISSIONS = ("delivery", "walls")  # delivery in the open room, and around walls
# patrol: the same message budget and the same silence — ALLIANCE's heartbeat against
# MURDOCH's lease renewal, τ against the lease
MATCHED = {"alliance": {"robot*.broadcast_rate": 2.0, "robot*.timeout_duration": 2.0},
           "murdoch": {"robot*.renewal_period": 0.5, "robot*.lease_timeout": 2.0}}
# delivery: the same two, and the route architectures' report period and stall watch
MATCHED_DELIVERY = {**MATCHED,
                    "central": {"robot*.report_period": 1.0,
                                "dispatcher*.progress_timeout": 10.0},
                    "ssi": {"robot*.report_period": 1.0, "robot*.progress_timeout": 10.0},
                    "cbba": {"robot*.report_period": 1.0, "robot*.progress_timeout": 10.0}}
# each fault model's spec, by role or channel (module docstring); {at} is --fault-at
FAULT_SPECS = {"none": "none", "crash": "crash:@first@{at}", "stall": "stall:@first@{at}",
               "partition": "partition:@first@{at}+10", "loss": "loss:0.2",
               "latency": "latency:0.5+-0.2", "range": "range:4",
               "dispatcher": "crash:dispatcher@{at}"}
FAULT_MODELS = tuple(FAULT_SPECS)
# the fault models only some architectures can suffer: elsewhere the tables say "n/a"
ONLY = {"dispatcher": ("central",)}
# robot2 holds border_protection from 0.6 s in every seed; its φ (600 s) is longer than a run.
# Patrol's channel faults are delivery's; range has no meaning for patrol's fixed posts.
PATROL_FAULTS = {"none": "none", "crash": "robot2@20", "stall": "stall:robot2@20",
                 "partition": "partition:robot2@20+10", "loss": "loss:0.2",
                 "latency": "latency:0.5+-0.2"}
OBJECTIVES = ("minsum", "makespan", "flowtime")
COORDINATION = "coordination_messages_per_second"
PER_ROBOT = "metrics.coordination_per_robot"  # coordination messages/s ÷ N (with_gaps)
DELIVERY_METRICS = ("metrics.completed", "metrics.makespan", "metrics.optimality",
                    *(f"metrics.objective_{o}" for o in OBJECTIVES),
                    *(f"metrics.gap_{o}" for o in OBJECTIVES),
                    "metrics.mean_waiting_time", "takeover_seconds", COORDINATION, PER_ROBOT)
PATROL_METRICS = ("first_full_allocation", "takeover_seconds", "*.exactly_one", COORDINATION)
# the report's plots the page shows: each figure against the team size, and two profiles
PICTURES = ("team_size_metrics.makespan.png", "team_size_metrics.optimality.png",
            "team_size_metrics.gap_minsum.png", "team_size_metrics.completed.png",
            f"team_size_{PER_ROBOT}.png", "team_size_takeover_seconds.png",
            "profile_metrics.objective_minsum.png", "profile_metrics.makespan.png")
WALL_SEEDS = 1000  # walled instance i has the generator's seed --instance-seed + 1000 + i
TABLE = ("<!-- table: begin -->", "<!-- table: end -->")
STUDY = ("<!-- study: begin -->", "<!-- study: end -->")


def delivery_fault(name: str, at: float) -> str:
    """The spec of a fault model, named by role or channel so it fits every team."""
    return FAULT_SPECS[name].format(at=f"{at:g}")


def applies(fault: str, arch: str) -> bool:
    """Whether `arch` can suffer the fault model at all (a dispatcher crash needs a dispatcher)."""
    return arch in ONLY.get(fault, (arch,))


def delivery_experiment(arch: str, args: argparse.Namespace) -> dict:
    return {"application": "delivery", "architecture": arch, "duration": args.duration,
            "seeds": args.seeds,
            "failures": [delivery_fault(f, args.fault_at) for f in args.faults
                         if applies(f, arch)],
            "instances": {"generator": "delivery", "robots": args.robots,
                          "tasks_per_robot": args.tasks_per_robot, "count": args.instances,
                          "seed": args.instance_seed,
                          **({"parameters": {"walls": args.walls}} if args.walls else {})},
            **({"overrides": {k: [v] for k, v in MATCHED_DELIVERY[arch].items()}}
               if arch in MATCHED_DELIVERY else {})}


def walls_args(args: argparse.Namespace) -> argparse.Namespace:
    """The walled instances' matrix: delivery's, with its own sizes, count, faults and
    instance seeds (WALL_SEEDS on: other instances than the open room's)."""
    return argparse.Namespace(**{**vars(args), "robots": args.walls_robots,
                                 "tasks_per_robot": args.walls_tasks_per_robot,
                                 "instances": args.walls_instances, "faults": args.walls_faults,
                                 "instance_seed": args.instance_seed + WALL_SEEDS})


def large_args(args: argparse.Namespace) -> argparse.Namespace:
    """The larger teams' matrix (--large-robots): delivery's, with fewer instances and faults
    (a 10-robot run costs 2-3 times a 5-robot one); its rows join delivery's report."""
    return argparse.Namespace(**{**vars(args), "robots": args.large_robots, "walls": 0,
                                 "instances": args.large_instances,
                                 "faults": args.large_faults})


def mission_args(mission: str, args: argparse.Namespace) -> argparse.Namespace:
    return walls_args(args) if mission == "walls" else \
        argparse.Namespace(**{**vars(args), "walls": 0})


LARGE_RUNS = 100_000  # the larger teams' run numbers follow delivery's from here


def mission_results(out: Path, mission: str, arch: str, args: argparse.Namespace) -> list[dict]:
    """One architecture's rows of a mission; delivery's with the larger teams' after them
    (run numbers from LARGE_RUNS on, so every row of the report stays one run)."""
    margs = mission_args(mission, args)
    if mission not in ROUTE_MISSIONS:
        return run_or_reuse(out, mission, arch, patrol_experiment(arch, margs), args)
    rows = run_or_reuse(out, mission, arch, delivery_experiment(arch, margs), args)
    if mission == "delivery" and args.large_robots:
        large = run_or_reuse(out, "large", arch, delivery_experiment(arch, large_args(args)),
                             args)
        rows = rows + [{**r, "run": LARGE_RUNS + int(r["run"])} for r in large]
    return rows


def patrol_experiment(arch: str, args: argparse.Namespace) -> dict:
    return {"application": "patrol", "architecture": arch, "duration": args.patrol_duration,
            "seeds": args.patrol_seeds,
            "failures": [PATROL_FAULTS[f] for f in args.patrol_faults],
            "overrides": {k: [v] for k, v in MATCHED[arch].items()}}


def run_or_reuse(out: Path, mission: str, arch: str, experiment: dict,
                 args: argparse.Namespace) -> list[dict]:
    """One architecture's results on a mission: OUTPUT/<mission>_<arch>/results.csv. With
    --reuse, results already there are read, not run again — refused when the experiment file
    beside them asked for another matrix (results of another study must not be mixed in)."""
    folder, file = out / f"{mission}_{arch}", out / f"{mission}_{arch}.yaml"
    if args.reuse and (folder / "results.csv").is_file():
        if file.is_file() and yaml.safe_load(file.read_text()) != experiment:
            raise ConfigError("another matrix than this command's: give its options, or "
                              "another --output", file=str(file))
        return read_results(folder / "results.csv").rows
    write_text(file, yaml.safe_dump(experiment, sort_keys=False, allow_unicode=True))
    return run_experiment(file=file, output=folder, jobs=None if args.scheduler else args.jobs,
                          scheduler=args.scheduler, plots=False)


def with_gaps(row: dict) -> dict:
    """The row with each objective's gap to its reference (achieved ÷ reference − 1, in %) and
    the reference under the report's name for it; blank where either value is missing (a task
    never served has no objective value); and the coordination traffic per robot."""
    out = dict(row)
    traffic, n = _number(row.get(COORDINATION)), _number(row.get("n_robots"))
    out[PER_ROBOT] = "" if traffic is None or not n else round(traffic / n, 4)
    for o in OBJECTIVES:
        achieved, ref = _number(row.get(f"metrics.objective_{o}")), \
            _number(row.get(f"metrics.reference_{o}"))
        out[f"metrics.reference_objective_{o}"] = row.get(f"metrics.reference_{o}", "")
        out[f"metrics.gap_{o}"] = "" if achieved is None or not ref else \
            round((achieved / ref - 1.0) * 100.0, 3)
    return out


def _number(text) -> float | None:
    try:
        x = float(text)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def combined(folder: Path, mission: str, results: dict[str, list[dict]]) -> Path:
    """Every architecture's rows of one mission as one results.csv, each naming its
    architecture and application, so the report pairs the runs of one instance and seed."""
    rows = []
    for arch, arch_rows in results.items():
        for r in arch_rows:
            routes = mission in ROUTE_MISSIONS
            row = {**r, "architecture": arch, "application": "delivery" if routes else mission}
            if routes:  # the matched parameters are the architecture's, fixed: not a cell's
                row = {k: v for k, v in row.items() if k not in MATCHED_DELIVERY.get(arch, {})}
            rows.append(with_gaps(row) if routes else row)
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(folder / "results.csv", rows, [])
    return folder / "results.csv"


def metrics_of(wanted: tuple[str, ...], path: Path) -> tuple[str, ...]:
    columns = read_results(path).columns
    out: list[str] = []
    for m in wanted:
        if m.startswith("*"):
            out += sorted(c for c in columns if c.endswith(m[1:]))
        elif m in columns:
            out.append(m)
    return tuple(out)


def large_line(args, mission: str) -> str:
    """The larger teams' part of delivery's matrix, in words (compare_architectures.large_args)."""
    if mission != "delivery" or not getattr(args, "large_robots", None):
        return ""
    return (f"Larger teams beside them, N = {', '.join(map(str, args.large_robots))} (M = "
            f"{', '.join(f'{k:g}' for k in args.tasks_per_robot)} × N): "
            f"{args.large_instances} instance{'s' if args.large_instances > 1 else ''} per size "
            f"and the faults {', '.join(args.large_faults)} only. ")


def matrix_intro(report: Report, args: argparse.Namespace, mission: str) -> str:
    """What a mission's rows are a matrix of, in words, from this command's options."""
    rows = report.table.rows
    failed = [r for r in rows if r.get("status") != "ok"]
    archs = list(args.architectures)
    sizes = sorted({size_of(c) for c in report.cells})
    return (f"Delivery: {len(rows)} runs — {len(archs)} architectures ({', '.join(archs)}) × "
            f"{len(sizes)} sizes (N robots, M tasks: "
            + ", ".join(f"{n}/{m}" for n, m in sizes)
            + f") × {args.instances} generated instances each (seed {args.instance_seed} on"
            + (f", {args.walls} walls each" if args.walls else "") + ") × "
            f"{len(args.faults)} fault models (by role or channel, at {args.fault_at:g} s; "
            "the dispatcher crash under central only) × "
            f"{len(args.seeds)} seed{'s' if len(args.seeds) > 1 else ''}, "
            f"{args.duration:g} simulated s each, lockstep; {len(failed)} failed. Each cell: "
            "the mean and its 95 % bootstrap interval over instances (docs/statistics.md); a "
            "gap is the objective achieved over its reference − 1, in %. "
            + large_line(args, mission) + references_line(report))


def headline_intro(args: argparse.Namespace) -> str:
    return (f"Generated delivery instances (N = {', '.join(map(str, args.robots))}, M = N and "
            f"2N, {args.instances} instances each; N = "
            f"{', '.join(map(str, getattr(args, 'large_robots', []) or ['–']))} with "
            f"{getattr(args, 'large_instances', 0)}), every fault model, matched parameters, "
            "lockstep; mean and 95 % bootstrap interval over instances "
            "([docs/comparison.md](docs/comparison.md) has every figure, the paired "
            "comparisons and what was scaled down). Patrol: ALLIANCE and MURDOCH only.")


def parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--missions", nargs="+", choices=("delivery", "walls", "patrol"),
                    default=["delivery", "walls", "patrol"],
                    help="walls: delivery on instances with walls (--walls …)")
    ap.add_argument("--architectures", nargs="+", default=list(DELIVERY_ARCHITECTURES),
                    help="delivery's architectures (registered ones: mrta arch list)")
    ap.add_argument("--baseline", default="central",
                    help="delivery's paired comparisons read ARCH − BASELINE (patrol: murdoch)")
    ap.add_argument("--robots", type=int, nargs="+", default=[5], help="team sizes N")
    ap.add_argument("--tasks-per-robot", type=float, nargs="+", default=[1.0, 2.0],
                    help="M = k · N for each k")
    ap.add_argument("--instances", type=int, default=1, help="instances per size")
    ap.add_argument("--instance-seed", type=int, default=2,
                    help="instance i of a size is the generator's with this seed + i")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1], help="runs' seeds")
    ap.add_argument("--duration", type=float, default=90.0, help="delivery, simulated s")
    ap.add_argument("--fault-at", type=float, default=5.0, help="delivery faults' time, s")
    ap.add_argument("--patrol-seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--patrol-duration", type=float, default=60.0)
    ap.add_argument("--faults", nargs="+", choices=FAULT_MODELS, default=list(FAULT_MODELS))
    ap.add_argument("--large-robots", type=int, nargs="*", default=[10],
                    help="larger team sizes N, in delivery's report with fewer instances and "
                         "faults (--large-instances, --large-faults)")
    ap.add_argument("--large-instances", type=int, default=1)
    ap.add_argument("--large-faults", nargs="+", choices=FAULT_MODELS, default=["none"])
    ap.add_argument("--patrol-faults", nargs="+", choices=tuple(PATROL_FAULTS),
                    default=["none", "crash", "stall"], help="patrol's fault models")
    ap.add_argument("--walls", type=int, default=2, help="walls in each walled instance")
    ap.add_argument("--walls-robots", type=int, nargs="+", default=[5],
                    help="walled instances' team sizes N")
    ap.add_argument("--walls-tasks-per-robot", type=float, nargs="+", default=[1.0])
    ap.add_argument("--walls-instances", type=int, default=2, help="walled instances per size")
    ap.add_argument("--walls-faults", nargs="+", choices=FAULT_MODELS,
                    default=["none"], help="the walled instances' faults")
    ap.add_argument("--jobs", type=int, default=2, help="runs at once on this machine")
    ap.add_argument("--scheduler", default=None,
                    help="a Dask scheduler's address: runs as tasks on its cluster")
    ap.add_argument("--output", type=Path, default=None, help="runs and tables (default: tmp)")
    ap.add_argument("--reuse", action="store_true",
                    help="results already in OUTPUT are read, not run again")
    add_doc_options(ap)
    args = ap.parse_args(argv)
    known = architecture_names()
    unknown = [a for a in args.architectures if a not in known]
    if unknown:
        ap.error(f"architecture {unknown[0]!r} is not registered (registered: "
                 f"{', '.join(known)})")
    if args.baseline not in args.architectures:
        ap.error(f"--baseline {args.baseline!r} is not among --architectures")
    return args


def add_doc_options(ap: argparse.ArgumentParser) -> None:
    """The options write_docs reads (`--write-docs`, `--doc`, `--readme`, `--no-plots`): one
    spelling for this script and study_report.py, which both write docs/comparison.md."""
    ap.add_argument("--no-plots", action="store_true", help="no report plots")
    ap.add_argument("--write-docs", action="store_true",
                    help="also rewrite docs/comparison.md's block, the README's headline and "
                         "docs/img/study/ (default: write only into OUTPUT)")
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "comparison.md")
    ap.add_argument("--readme", type=Path, default=ROOT / "README.md")


def write_docs(args: argparse.Namespace, table: str, short: str, out: Path,
               delivery: bool) -> list[str]:
    """docs/comparison.md's block (`args.doc`), the README's headline (`args.readme`) and the
    plots the page shows (docs/img/study/, from OUT/delivery/); the pictures written."""
    replace_block(args.doc, TABLE, table)
    replace_block(args.readme, STUDY, short)
    pictures = []
    if delivery and not args.no_plots:
        img = args.doc.parent / "img" / "study"
        img.mkdir(parents=True, exist_ok=True)
        for name in PICTURES:
            if (out / "delivery" / name).is_file():
                data = (out / "delivery" / name).read_bytes()
                write_atomically(img / name, lambda tmp, data=data: tmp.write_bytes(data))
                pictures.append(str(img / name))
    return pictures


def exit_code(main) -> int:
    """`main()`'s code, a usage error one line and exit 2 as `mrta` does, a runtime error 1."""
    try:
        return main()
    except ConfigError as exc:
        return print(f"Error: {exc}", file=sys.stderr) or 2
    except MrtaRuntimeError as exc:
        return print(f"Error: {exc}", file=sys.stderr) or 1


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    out = args.output or Path(tempfile.mkdtemp(prefix="mrta-study-"))
    out.mkdir(parents=True, exist_ok=True)
    reports: dict[str, Report] = {}
    sections: list[str] = []
    for mission in args.missions:
        routes = mission in ROUTE_MISSIONS  # delivery, in an open room or around walls
        archs = args.architectures if routes else PATROL_ARCHITECTURES
        margs = mission_args(mission, args)
        results = {a: mission_results(out, mission, a, args) for a in archs}
        for arch, rows in results.items():
            for r in rows:
                if r.get("status") != "ok":
                    print(json.dumps({"failed_run": r.get("run"), "mission": mission,
                                      "architecture": arch, "error": r.get("error")}),
                          flush=True)
        path = combined(out / mission, mission, results)
        wanted = DELIVERY_METRICS if routes else PATROL_METRICS
        baseline = args.baseline if routes else "murdoch"
        baseline = baseline if len(archs) > 1 else None  # one architecture: nothing to pair
        reports[mission] = write_report(path, out / mission, Options(
            baseline=baseline, metrics=metrics_of(wanted, path), plots=not args.no_plots))
        json_lines(mission, reports[mission])
        sections += (delivery_tables(reports[mission], list(args.architectures),
                                     matrix_intro(reports[mission], margs, mission), mission)
                     if routes
                     else mission_tables(mission, out / mission)) + [""]
    table = "\n".join(sections).rstrip()
    short = "\n".join(headline(reports, list(args.architectures), headline_intro(args)))
    write_text(out / "tables.md", table + "\n\n" + short + "\n")
    pictures = write_docs(args, table, short, out, "delivery" in reports) \
        if args.write_docs else []
    print(json.dumps({"tables": str(out / "tables.md"), "runs": str(out),
                      "docs_rewritten": [str(args.doc), str(args.readme)] + pictures
                      if args.write_docs else []}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(exit_code(main))
