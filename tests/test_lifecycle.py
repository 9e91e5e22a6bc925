"""Resources are context managers one way (mrta_zenoh.lifecycle.Closing): `with` gives the
resource itself and closes it on the way out, also when the block raises; and no class writes
the `__enter__` / `__exit__` pair again, which the source is read for."""

import ast

import pytest

from mrta_zenoh.bus import InProcBus
from mrta_zenoh.lifecycle import Closing
from tests.harness import source_tree
from tests.harness.helpers import ROOT

SOURCES = [ROOT / "mrta_zenoh", ROOT / "robot_agent", ROOT / "simulator", ROOT / "supervisor",
           ROOT / "configs", ROOT / "examples", ROOT / "tests", ROOT / "benchmarks"]


class _Counted(Closing):
    def __init__(self) -> None:
        self.closed = 0

    def close(self) -> None:
        self.closed += 1


def test_with_gives_the_resource_and_closes_it_once():
    with _Counted() as r:
        assert isinstance(r, _Counted) and r.closed == 0
    assert r.closed == 1


def test_a_block_that_raises_still_closes_and_the_error_goes_on():
    r = _Counted()
    with pytest.raises(ValueError, match="boom"):
        with r:
            raise ValueError("boom")
    assert r.closed == 1


def test_a_closing_without_close_says_so():
    class Forgot(Closing):
        pass

    with pytest.raises(NotImplementedError, match="Forgot must define close"):
        with Forgot():
            pass


def test_the_bus_and_its_handles_close_through_the_mixin():
    with InProcBus() as bus:
        with bus.subscribe("a/**", lambda s: None) as sub, bus.declare_token("t") as token:
            assert sub in bus._subs and token in bus._tokens
        assert sub not in bus._subs and token not in bus._tokens
    assert bus.closed


def _pair_written_out(cls: ast.ClassDef) -> bool:
    """An `__exit__` that only calls self.close(): Closing's, written again."""
    for node in cls.body:
        if isinstance(node, ast.FunctionDef) and node.name == "__exit__":
            body = [n for n in node.body if not (isinstance(n, ast.Expr)
                                                  and isinstance(n.value, ast.Constant))]
            return len(body) == 1 and ast.unparse(body[0]) == "self.close()"
    return False


def test_no_class_writes_the_closing_pair_again():
    found = [f"{f.relative_to(ROOT)}:{node.lineno} {node.name}"
             for folder in SOURCES for f in source_tree.python_files(folder)
             if f.name != "lifecycle.py"
             for node in source_tree.nodes(f)
             if isinstance(node, ast.ClassDef) and _pair_written_out(node)]
    assert not found, "derive from mrta_zenoh.lifecycle.Closing instead:\n" + "\n".join(found)
