"""Fixtures, and the tiers: a test that starts a process or opens a Zenoh session must be marked
`multiprocess` (pyproject.toml), so `pytest -m "not multiprocess"` — the fast tier — never depends
on real networking; an unmarked one fails, saying so. The fast tier, like the CI tier (`pytest`,
pyproject.toml's addopts), leaves out the tests marked `slow`, so it stays under a minute; they
run in the whole suite (`pytest -m "not browser"`), or alone with `pytest -m slow` (an expression
that names `slow` keeps them). The folders, the harnesses and the conformance suite:
tests/README.md."""

import itertools
import os
import re
import subprocess
import sys
from pathlib import Path

# Bytecode caches, whatever the calling shell says (some sandboxes set PYTHONDONTWRITEBYTECODE):
# the suite starts hundreds of Python processes over the same sources, and without caches each
# compiles the project from source — each xdist worker's collection (assertion rewriting
# included) took 24 CPU-s instead of 10, each child ≈ 0.2 s more. Python's default; the caches
# sit in __pycache__ folders, which git ignores. Set before anything of the project is imported,
# and for the children (and xdist's workers) through the environment.
sys.dont_write_bytecode = False
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

import pytest  # noqa: E402 (after the bytecode setting)
from _pytest.mark.expression import Expression  # noqa: E402 (-m's own parser)

from tests.harness.helpers import REFERENCE, Children, Tokens  # noqa: E402


PROCESS = Path(__file__).resolve().parent / "process"


class UnmarkedMultiprocess(BaseException):
    """Raised where an unmarked test starts a process or opens a Zenoh session. A BaseException,
    so code that turns errors into exit codes (`except Exception`) does not hide it."""


def _selects_no_multiprocess(expr: str) -> bool:
    """Whether `-m expr` deselects every test marked `multiprocess`, whatever other marks it has
    (each name the expression uses tried on and off)."""
    if "multiprocess" not in expr:
        return False
    compiled = Expression.compile(expr)
    names = sorted(set(re.findall(r"[A-Za-z_][\w.]*", expr)) - {"and", "or", "not"})
    return not any(compiled.evaluate(lambda name, **_: name == "multiprocess" or name in on)
                   for k in range(len(names) + 1) for on in itertools.combinations(names, k))


def pytest_ignore_collect(collection_path, config):
    """tests/process/ holds only modules whose every test is `multiprocess` (tests/test_layering.py
    keeps it so): where the mark expression leaves every such test out (the fast tier), the
    folder is not imported at all — each xdist worker would otherwise import its 50 modules, and
    scipy.optimize, dask and distributed through them, to deselect every test it collected."""
    if collection_path == PROCESS and _selects_no_multiprocess(config.option.markexpr or ""):
        return True
    return None


def pytest_collection_modifyitems(config, items):
    expr = config.option.markexpr or ""
    if "not multiprocess" not in expr or "slow" in expr:
        return
    fast = [item for item in items if item.get_closest_marker("slow") is None]
    if len(fast) < len(items):
        config.hook.pytest_deselected(items=[i for i in items if i not in fast])
        items[:] = fast


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    if report.when == "call":
        item.call_failed = report.failed


@pytest.fixture(autouse=True)
def _multiprocess_only_when_marked(request, monkeypatch):
    if request.node.get_closest_marker("multiprocess") is not None:
        yield
        return
    import zenoh

    violations: list[str] = []

    def refuse(what):
        def refused(*args, **kwargs):
            message = (f"{request.node.nodeid} {what} but is not marked multiprocess "
                       "(add @pytest.mark.multiprocess, or pytestmark for the whole file)")
            violations.append(message)
            raise UnmarkedMultiprocess(message)
        return refused

    monkeypatch.setattr(subprocess, "Popen", refuse("starts a process"))
    monkeypatch.setattr(zenoh, "open", refuse("opens a Zenoh session"))
    yield
    if violations and not getattr(request.node, "call_failed", False):  # caught on the way
        pytest.fail(violations[0], pytrace=False)


@pytest.fixture(autouse=True)
def _close_token_watchers():
    """A Zenoh session left open in the test process would hang it at exit."""
    yield
    for watcher in list(Tokens.open_watchers):
        watcher.close()


@pytest.fixture
def children():
    c = Children()
    try:
        yield c
    finally:
        c.stop_all()


@pytest.fixture
def tokens(children):
    """Liveliness tokens on the children's bus (tests.harness.helpers.Tokens): readiness, not log lines."""
    t = Tokens(children.rendezvous)
    try:
        yield t
    finally:
        t.close()


@pytest.fixture
def reference():
    """The original project's files the tests read, vendored under tests/data/reference."""
    assert REFERENCE.is_dir(), f"{REFERENCE} is missing"
    return REFERENCE
