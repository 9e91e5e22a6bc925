"""The framework/application split, checked on the source: who may import whom.

mrta_zenoh (the core) knows no architecture, simulator, supervisor or application; robot_agent
(ALLIANCE), simulator and supervisor build on the core only and never on each other or on an
application; the patrol application reaches the framework only through public modules and is
itself reached only through entry points.
"""

import ast
from pathlib import Path

import pytest

from tests.helpers import ROOT

PACKAGES = {
    "mrta_zenoh": ROOT / "mrta_zenoh",
    "robot_agent": ROOT / "robot_agent",
    "simulator": ROOT / "simulator",
    "supervisor": ROOT / "supervisor",
    "mrta_murdoch": ROOT / "configs" / "architectures" / "murdoch",
    "mrta_patrol": ROOT / "configs" / "applications" / "patrol",
    "mrta_patrol_murdoch": ROOT / "configs" / "applications" / "patrol_murdoch",
}
FORBIDDEN = {
    "mrta_zenoh": {"robot_agent", "simulator", "supervisor", "mrta_murdoch", "mrta_patrol",
                   "mrta_patrol_murdoch", "ping_app"},
    "robot_agent": {"simulator", "supervisor", "mrta_murdoch", "mrta_patrol",
                    "mrta_patrol_murdoch"},
    # MURDOCH shares robot_agent's low level (plugins, loop, hosting) and nothing else
    "mrta_murdoch": {"simulator", "supervisor", "mrta_patrol", "mrta_patrol_murdoch"},
    "simulator": {"robot_agent", "supervisor", "mrta_murdoch", "mrta_patrol"},
    "supervisor": {"robot_agent", "simulator", "mrta_murdoch", "mrta_patrol"},
    "mrta_patrol": set(),
    "mrta_patrol_murdoch": {"mrta_zenoh", "robot_agent", "mrta_murdoch", "simulator",
                            "supervisor", "mrta_patrol"},  # holds no code at all
}
PATROL_WORDS = ("patrol", "wander", "border_protection", "report_due", "wall_in_range")


def imports_of(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            out.add(node.module.split(".")[0])
    return out


@pytest.mark.parametrize("package", list(PACKAGES))
def test_no_package_imports_what_it_must_not_know(package):
    bad = []
    for f in sorted(PACKAGES[package].rglob("*.py")):
        hit = imports_of(f) & FORBIDDEN[package]
        if hit:
            bad.append(f"{f.relative_to(ROOT)} imports {', '.join(sorted(hit))}")
    assert not bad, "\n".join(bad)


def test_the_framework_has_no_patrol_specific_code():
    """Not even by name: robot_agent, simulator, supervisor and the core never mention the
    patrol application's plugins, messages or keys (docstrings aside)."""
    bad = []
    for package in ("mrta_zenoh", "robot_agent", "mrta_murdoch", "simulator", "supervisor"):
        for f in sorted(PACKAGES[package].rglob("*.py")):
            tree = ast.parse(f.read_text(encoding="utf-8"))
            docstrings = {id(n.body[0].value) for n in ast.walk(tree)
                          if isinstance(n, (ast.Module, ast.ClassDef, ast.FunctionDef))
                          and n.body and isinstance(n.body[0], ast.Expr)
                          and isinstance(n.body[0].value, ast.Constant)}
            for node in ast.walk(tree):
                if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                        and id(node) not in docstrings \
                        and any(w in node.value for w in ("patrol_msgs", "patrol/", "wander",
                                                          "border_protection")):
                    bad.append(f"{f.relative_to(ROOT)}:{node.lineno}: {node.value[:60]!r}")
    assert not bad, "\n".join(bad)
