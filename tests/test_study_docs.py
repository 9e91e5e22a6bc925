"""The study shipped in docs/study/ (issue 48.5): its files are the matrix docs/study/README.md
describes, its runs start pairs first, and docs/comparison.md's tables and the README's
headline are what `benchmarks/study_report.py` writes from the committed rows."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import msgspec
import yaml

from mrta_supervisor.experiment.api import paired_first, resolve_all
from mrta_supervisor.experiment.file import load_experiment
from mrta_supervisor.experiment.instances import prepare
from mrta_supervisor.experiment.resume import identity_of, read_identity
from robot_agent.central.params import PROGRESS_TIMEOUT as CENTRAL_WATCH
from robot_agent.route.own_route_params import PROGRESS_TIMEOUT as ROUTE_WATCH
from tests.harness.helpers import ROOT

STUDY = ROOT / "docs" / "study"
ARCHS = ["alliance", "murdoch", "central", "ssi", "cbba"]
FAULTS = {"none", "crash:@first@5", "stall:@first@5", "partition:@first@5+10", "loss:0.2",
          "latency:0.5+-0.2", "range:4"}


def study_report():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    spec = importlib.util.spec_from_file_location("study_report",
                                                  ROOT / "benchmarks" / "study_report.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def block(text: str, begin: str, end: str) -> str:
    return text.split(begin + "\n", 1)[1].split("\n" + end, 1)[0]


def made(path: Path, folder: Path, count: int = 2):
    """The study file's experiment with its first `count` instances made into `folder`."""
    exp = load_experiment(path)
    spec = msgspec.structs.replace(exp.spec.instances, count=count)
    return exp.with_instances(prepare(spec, "delivery", exp.file.parent, folder, exp.doc))


def test_comparison_tables_and_headline_are_the_reports_of_the_committed_rows(tmp_path):
    mod = study_report()
    table, short, _ = mod.tables(STUDY, tmp_path, plots=False)
    assert block((ROOT / "docs" / "comparison.md").read_text(), *mod.TABLE) == table
    assert block((ROOT / "README.md").read_text(), *mod.STUDY) == short
    # docs/study/README.md says which files are complete, which partial (and how far)
    assert block((STUDY / "README.md").read_text(), *mod.STATUS) == \
        mod.status(mod.study_files(STUDY))


def test_every_delivery_size_has_every_architecture_under_every_fault_model():
    files = [load_experiment(p) for p in sorted(STUDY.glob("[0-9][0-9]-delivery-*.yaml"))]
    by_size: dict[tuple, set] = {}
    for exp in files:
        block_ = exp.spec.instances
        assert block_.generator == "delivery" and block_.count >= 10
        size = (block_.robots[0], block_.tasks[0], block_.parameters.get("walls", 0))
        for arch in exp.spec.architectures or [exp.spec.architecture]:
            for fault in exp.spec.failures:
                by_size.setdefault(size, set()).add((arch, fault))
    for (n, m, walls), cells in by_size.items():
        if n in (5, 10, 20) and not walls:
            assert cells >= {(a, f) for a in ARCHS for f in FAULTS}, (n, m)
            assert ("central", "crash:dispatcher@5") in cells, (n, m)
            assert all(e.spec.instances.count >= 30 for e in files
                       if e.spec.instances.robots[0] == n)
    assert {(n, m) for n, m, w in by_size if not w} >= {(n, k * n) for n in (5, 10, 20)
                                                        for k in (1, 2)}


def test_the_packages_generated_for_the_study_hold_the_matched_parameters(tmp_path):
    """No overrides in the delivery files: the generator's packages are matched as
    docs/comparison.md says (2 Hz heartbeat or lease renewal, 2 s of silence; route
    architectures report every 1 s and watch for 10 s without progress)."""
    exp = made(STUDY / "01-delivery-5x5-none.yaml", tmp_path / "i", count=1)
    next(iter(resolve_all(exp).values())).mission.derive(exp.instances[0].path, tmp_path / "d")

    def values(package: str, stem: str, key: str, default=None) -> set:
        files = sorted((tmp_path / "d" / package / "config").glob(f"{stem}*_params.yaml"))
        assert files, (package, stem)
        return {yaml.safe_load(f.read_text()).get(key, default) for f in files}

    assert values("delivery", "robot", "broadcast_rate") == {2.0}
    assert values("delivery", "robot", "timeout_duration") == {2.0}
    assert values("delivery_murdoch", "robot", "renewal_period") == {0.5}
    assert values("delivery_murdoch", "robot", "lease_timeout") == {2.0}
    for package in ("delivery_central", "delivery_ssi", "delivery_cbba"):
        assert values(package, "robot", "report_period") == {1.0}
    assert values("delivery_central", "dispatcher", "progress_timeout", CENTRAL_WATCH) == {10.0}
    for package in ("delivery_ssi", "delivery_cbba"):
        assert values(package, "robot", "progress_timeout", ROUTE_WATCH) == {10.0}


def test_runs_start_pairs_first_and_keep_their_numbers(tmp_path):
    exp = made(STUDY / "01-delivery-5x5-none.yaml", tmp_path)
    runs = exp.runs(instances=exp.instances)
    order = paired_first(exp, runs)
    assert sorted(r.index for r in order) == [r.index for r in runs]
    # every architecture on the first instance, then every architecture on the second
    first = order[:5]
    assert [r.architecture for r in first] == ARCHS
    assert {r.instance.name for r in first} == {exp.instances[0].name}
    assert {r.instance.name for r in order[5:10]} == {exp.instances[1].name}
    patrol = load_experiment(STUDY / "17-patrol-alliance-none-crash-stall.yaml")
    seeds = [r.seed for r in paired_first(patrol, patrol.runs())]
    assert seeds[:3] == [1, 1, 1] and seeds[3:6] == [2, 2, 2]  # each failure, seed by seed


def test_every_committed_folder_resumes_under_its_file(tmp_path):
    """A committed folder's experiment.json is the digest of the matrix its file makes today
    (the instances regenerated byte for byte): otherwise `run.sh` refuses to resume it, and the
    study cannot continue from its committed rows (it happened: a new empty field in every
    generated instance file)."""
    folders = sorted(p.parent for p in STUDY.glob("*/experiment.json"))
    assert folders
    made_for: dict[str, tuple] = {}  # the files of one size share their instances: made once
    for folder in folders:
        exp = load_experiment(STUDY / f"{folder.name}.yaml")
        key = msgspec.json.encode(exp.spec.instances).decode()
        if key not in made_for:
            made_for[key] = prepare(exp.spec.instances, "delivery", exp.file.parent,
                                    tmp_path / str(len(made_for)), exp.doc)
        exp = exp.with_instances(made_for[key])
        assert identity_of(exp, exp.runs(), None).digest == read_identity(folder).digest, folder


def test_a_file_in_progress_is_listed_but_none_of_its_rows_is_reported(tmp_path):
    """A cell short of its instances is no figure of the study's: a file's rows reach the
    tables only once every run of its matrix has one (issue 48: ≥ 30 instances per cell)."""
    mod = study_report()
    exp = load_experiment(STUDY / "03-delivery-5x5-stall.yaml")
    row = {"run": "0", "architecture": "alliance", "status": "ok", "instance": "i"}
    partial = mod.StudyFile(3, exp, [row] * 4)
    whole = mod.StudyFile(3, exp, [{**row, "run": str(i)} for i in range(150)])
    assert not partial.complete and whole.complete
    assert mod.combined([partial], "delivery", tmp_path) is None
    lines = mod.coverage([partial], "delivery")
    assert "03-delivery-5x5-stall (in progress)" in lines[2] and "4/30" in lines[2]
    assert any("In progress, not in the tables" in line for line in lines)
    said = mod.status([partial, mod.StudyFile(3, exp, whole.rows)])
    assert "| 03-delivery-5x5-stall | **partial** (in no table) | 4 / 150 |" in said
    assert "| 03-delivery-5x5-stall | complete | 150 / 150 |" in said
    assert said.startswith("**1 of 2 files complete** (150 runs")
