"""The reference cache ($MRTA_REFERENCE_CACHE, mrta_zenoh/planning/reference.py): an
experiment's runs of one instance solve its references once — a later run reads the same value
and routes the solve gives, without solving — and runs of an instance get the folder beside
their instance file (experiment_runs.start_run)."""

from __future__ import annotations

import pytest

import importlib
from mrta_zenoh.planning.problem import Problem, Robot, Task
from mrta_zenoh.planning.reference import REFERENCE_CACHE_ENV, reference

# the module (the package exports its function under the same name)
ref_module = importlib.import_module("mrta_zenoh.planning.reference")


def problem(shift: float = 0.0) -> Problem:
    robots = (Robot("r1", (0.0, 0.0), 1.0), Robot("r2", (4.0, 0.0), 0.5))
    tasks = tuple(Task(f"t{i}", (float(i) + shift, 1.0), service=1.0) for i in range(4))
    return Problem(robots, tasks)


@pytest.fixture
def solves(monkeypatch):
    """How many times a reference was solved (not read back)."""
    calls = []
    real = ref_module._solve

    def counted(*args):
        calls.append(args[1])
        return real(*args)

    monkeypatch.setattr(ref_module, "_solve", counted)
    return calls


@pytest.mark.parametrize("objective", ["minsum", "makespan", "flowtime"])
def test_a_cached_reference_is_the_solves_own_and_is_solved_once(tmp_path, monkeypatch,
                                                                  solves, objective):
    monkeypatch.delenv(REFERENCE_CACHE_ENV, raising=False)
    solved = reference(problem(), objective)
    monkeypatch.setenv(REFERENCE_CACHE_ENV, str(tmp_path / "refs"))
    first, again = reference(problem(), objective), reference(problem(), objective)
    assert len(solves) == 2  # without the cache, then once into it; `again` read it
    for got in (first, again):
        assert (got.value, got.routes, got.method, got.proven_optimal, got.capped) == \
            (solved.value, solved.routes, solved.method, solved.proven_optimal, solved.capped)
        assert got.objective.value == objective


def test_another_problem_or_budget_is_another_entry(tmp_path, monkeypatch, solves):
    monkeypatch.setenv(REFERENCE_CACHE_ENV, str(tmp_path))
    a = reference(problem(), "minsum")
    b = reference(problem(shift=2.0), "minsum")
    reference(problem(), "minsum", exact_limit=3, solutions=50)  # the routing search instead
    assert len(solves) == 3 and a.value != b.value
    assert len(list(tmp_path.glob("*.json"))) == 3


def test_an_instance_run_gets_the_folder_beside_its_instance(tmp_path, monkeypatch):
    from mrta_supervisor.experiment.runs import REFERENCES, start_run
    from tests.test_instance_overrides import Group

    class Pkg:
        name, path = "delivery", tmp_path

    class Run:
        index, overrides, failure, seed, instance, agents_per_process = 0, (), "none", 1, None, 1

    monkeypatch.delenv(REFERENCE_CACHE_ENV, raising=False)
    group = Group()
    inst = tmp_path / "instances" / "i.yaml"
    start_run(group, Pkg, 10.0, Run, tmp_path, instance=inst)
    start_run(group, Pkg, 10.0, Run, tmp_path)  # the application's own instance: none
    assert group.started[0][1][REFERENCE_CACHE_ENV] == str(inst.parent / REFERENCES)
    assert REFERENCE_CACHE_ENV not in group.started[1][1]
    monkeypatch.setenv(REFERENCE_CACHE_ENV, "/elsewhere")  # the caller's folder is kept
    start_run(group, Pkg, 10.0, Run, tmp_path, instance=inst)
    assert REFERENCE_CACHE_ENV not in group.started[2][1]


KEY = """
import importlib, json, os, sys, tempfile
from pathlib import Path
from mrta_zenoh.planning.problem import Problem, Robot, Task
ref = importlib.import_module("mrta_zenoh.planning.reference")
os.environ[ref.REFERENCE_CACHE_ENV] = sys.argv[1]
robots = (Robot("r1", (0.0, 0.0), 1.0, frozenset({"lift", "cold", "heat", "dry", "wet"})),)
ref.reference(Problem(robots, (Task("t1", (1.0, 1.0), capability="cold"),)), "minsum")
"""


@pytest.mark.multiprocess
def test_runs_in_other_processes_find_the_same_entry(tmp_path):
    import os
    import subprocess
    import sys
    for hash_seed in ("1", "2", "3"):  # a set's order follows the process's string hashing
        subprocess.run([sys.executable, "-c", KEY, str(tmp_path)], check=True,
                       env={**os.environ, "PYTHONHASHSEED": hash_seed})
    assert len(list(tmp_path.glob("*.json"))) == 1
