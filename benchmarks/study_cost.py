"""What one run of the study costs, and where it goes (issue 48): `python benchmarks/study_cost.py`.

Each figure is one run exactly as `mrta experiment` starts it for a study file
(supervisor/experiment/runs.py `demo_args`: `mrta -q demo … --instance FILE --no-plots`, its
agents in hosts, the instance's reference values read from a warm cache as in a study, in the
environment the experiment gives its runs: runs.bytecode_cache), on the file's own first
instance: a child process tree whose CPU is read from /proc every 0.2 s, by
role (runner — `mrta demo`: packages derived, supervisor, analysis —, recorder, simulator,
agents; benchmarks/hosts.py). `--python` names the interpreters to compare (another checkout's
venv: the commit before a cut is the baseline of the same session; `PYTHON@before`: started as
experiments started runs before this session's cuts — no bytecode folder, a viewer's recording,
not `--recording bus`); their runs alternate, and
each line says whether its summary equals the first interpreter's but for the machine's fields
(mission/compare.run_differences). The reference cache is warmed by one run first (not printed).

    python benchmarks/study_cost.py [--file docs/study/01-delivery-5x5-none.yaml]
        [--architectures cbba] [--repeat 2] [--python /other/checkout/.venv/bin/python …]

One JSON line per run: interpreter, architecture, CPU-s in all and by role, wall s, load.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from hosts import emit, sample  # noqa: E402
from mrta_zenoh.planning.reference import REFERENCE_CACHE_ENV  # noqa: E402
from mrta_supervisor.experiment.api import resolve_all  # noqa: E402
from mrta_supervisor.experiment.file import load_experiment  # noqa: E402
from mrta_supervisor.experiment.instances import prepare  # noqa: E402
from mrta_supervisor.experiment.runs import bytecode_cache, demo_args  # noqa: E402
from mrta_supervisor.mission.compare import run_differences  # noqa: E402

BEFORE = "@before"


def one_run(python: str, args: list[str], out: Path, cache: Path, bytecode: dict) -> dict:
    """The run's CPU by role, wall and summary."""
    before = python.endswith(BEFORE)
    python = python.removesuffix(BEFORE)
    env = {**os.environ, REFERENCE_CACHE_ENV: str(cache), **({} if before else bytecode)}
    if before:
        at = args.index("--recording")
        args = args[:at] + args[at + 2:]
    t0, seen = time.monotonic(), {}
    # run in its own folder: `-m` puts the working directory first on the path, and a
    # checkout's would shadow another interpreter's code
    proc = subprocess.Popen([python, "-m", "mrta_zenoh.cli.main", *args], env=env, cwd=out,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        while proc.poll() is None:
            sample(proc.pid, seen)
            time.sleep(0.2)
    finally:
        if proc.poll() is None:
            proc.kill()
        err = proc.communicate()[1]
    by_role: dict[str, float] = {}
    for cpu, name in seen.values():
        by_role[name] = round(by_role.get(name, 0.0) + cpu, 2)
    summary = json.loads((out / "summary.json").read_text()) if proc.returncode == 0 else {}
    return {"rc": proc.returncode, "cpu_s": round(sum(by_role.values()), 2),
            "cpu_by_role": by_role, "wall_s": round(time.monotonic() - t0, 2),
            "summary": summary, "error": err.strip().splitlines()[-1:] if proc.returncode else []}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--file", type=Path, default=ROOT / "docs/study/01-delivery-5x5-none.yaml")
    ap.add_argument("--architectures", nargs="+", default=["cbba"])
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--python", nargs="+", default=[sys.executable])
    a = ap.parse_args()
    exp = load_experiment(a.file)
    with tempfile.TemporaryDirectory(prefix="mrta-study-cost-") as tmp, \
            bytecode_cache() as bytecode:
        folder = Path(tmp)
        exp = exp.with_instances(prepare(exp.spec.instances, exp.spec.application,
                                         exp.file.parent, folder, exp.doc))
        runs = {r.architecture: r for r in exp.runs(instances=exp.instances[:1])}
        packages = {name: run.package.name for name, run in resolve_all(exp).items()}
        cache = folder / "references"
        n = 0

        def run(python: str, arch: str) -> dict:
            nonlocal n
            n += 1
            out = folder / f"run{n}"
            out.mkdir()
            r = runs[arch]
            return one_run(python, demo_args(packages[arch], exp.spec.duration, r, out, False,
                                             r.instance.path), out, cache, bytecode)

        for python in a.python:  # the instance's references solved once; each checkout warm
            run(python, a.architectures[0])
        first: dict[str, dict] = {}
        for i in range(a.repeat):
            for arch in a.architectures:
                for python in a.python:
                    got = run(python, arch)
                    same = first.setdefault(arch, got["summary"])
                    emit(figure="study_run", python=python, architecture=arch,
                         file=a.file.name, instance=runs[arch].instance.name,
                         cpu_s=got["cpu_s"], cpu_by_role=got["cpu_by_role"],
                         wall_s=got["wall_s"], rc=got["rc"], error=got["error"],
                         same_summary=bool(got["summary"]) and not run_differences(
                             same, got["summary"]))


if __name__ == "__main__":
    main()
