"""The framework/application split, checked on the source: who may import whom.

mrta_zenoh (the core) knows no architecture, simulator, supervisor or application — it defines
the architecture contract, not an architecture. The agent runtime (mrta_agent.runtime) knows no
architecture and no route; the route family (mrta_agent.route: what central, SSI and CBBA share)
builds on the runtime and knows no architecture; ALLIANCE and MURDOCH build on the runtime, never
on the route family nor on each other; the simulator and the
supervisor build on the core only; applications reach an architecture only through its
registered contract (entry points), never by importing it.
"""

import ast
from pathlib import Path

import pytest

from tests.harness import source_tree
from tests.harness.helpers import ROOT

PACKAGES = {
    "mrta_zenoh": ROOT / "mrta_zenoh",
    "mrta_agent.runtime": ROOT / "robot_agent" / "runtime",
    "mrta_agent.route": ROOT / "robot_agent" / "route",
    "mrta_agent.alliance": ROOT / "robot_agent" / "alliance",
    "mrta_agent.murdoch": ROOT / "robot_agent" / "murdoch",
    "mrta_agent.central": ROOT / "robot_agent" / "central",
    "mrta_agent.ssi": ROOT / "robot_agent" / "ssi",
    "mrta_agent.cbba": ROOT / "robot_agent" / "cbba",
    "mrta_agent.tessi": ROOT / "robot_agent" / "tessi",
    "mrta_simulator": ROOT / "simulator",
    "mrta_supervisor": ROOT / "supervisor",
    "mrta_supervisor.live": ROOT / "supervisor" / "live",
    "mrta_supervisor.mission": ROOT / "supervisor" / "mission",
    "mrta_supervisor.experiment": ROOT / "supervisor" / "experiment",
    "mrta_patrol": ROOT / "configs" / "applications" / "patrol",
    "mrta_patrol_murdoch": ROOT / "configs" / "applications" / "patrol_murdoch",
    "mrta_delivery": ROOT / "configs" / "applications" / "delivery",
    "mrta_delivery_murdoch": ROOT / "configs" / "applications" / "delivery_murdoch",
    "mrta_delivery_central": ROOT / "configs" / "applications" / "delivery_central",
    "mrta_delivery_ssi": ROOT / "configs" / "applications" / "delivery_ssi",
    "mrta_delivery_cbba": ROOT / "configs" / "applications" / "delivery_cbba",
    "mrta_delivery_tessi": ROOT / "configs" / "applications" / "delivery_tessi",
}
APPS = {"mrta_patrol", "mrta_patrol_murdoch", "mrta_delivery", "mrta_delivery_murdoch",
        "mrta_delivery_central", "mrta_delivery_ssi", "mrta_delivery_cbba",
        "mrta_delivery_tessi", "ping_app"}
FORBIDDEN = {
    "mrta_zenoh": {"mrta_agent", "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_agent.runtime": {"mrta_agent.route", "mrta_agent.alliance", "mrta_agent.murdoch",
                           "mrta_agent.central", "mrta_agent.ssi", "mrta_agent.cbba",
                           "mrta_agent.tessi",
                           "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_agent.route": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_agent.central",
                         "mrta_agent.ssi", "mrta_agent.cbba", "mrta_agent.tessi",
                         "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_agent.alliance": {"mrta_agent.route", "mrta_agent.murdoch", "mrta_agent.central",
                            "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_agent.murdoch": {"mrta_agent.route", "mrta_agent.alliance", "mrta_agent.central",
                           "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_agent.central": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_simulator",
                           "mrta_supervisor"} | APPS,
    "mrta_agent.ssi": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_agent.cbba",
                       "mrta_agent.central", "mrta_agent.tessi", "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_agent.cbba": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_agent.ssi",
                        "mrta_agent.central", "mrta_agent.tessi", "mrta_simulator", "mrta_supervisor"} | APPS,
    # TeSSI is SSI with another bid: built on it (its rounds and reliability rules shared)
    "mrta_agent.tessi": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_agent.cbba",
                         "mrta_agent.central", "mrta_simulator", "mrta_supervisor"} | APPS,
    "mrta_simulator": {"mrta_agent", "mrta_supervisor"} | APPS,
    "mrta_supervisor": {"mrta_agent", "mrta_simulator"} | APPS,
    # supervisor/'s three rooms (supervisor/__init__.py): the live supervisor knows no experiment
    # and runs no mission; a mission knows no experiment; an experiment knows nothing live
    "mrta_supervisor.live": {"mrta_agent", "mrta_simulator", "mrta_supervisor.experiment"} | APPS,
    "mrta_supervisor.mission": {"mrta_agent", "mrta_simulator", "mrta_supervisor.experiment"}
    | APPS,
    "mrta_supervisor.experiment": {"mrta_agent", "mrta_simulator", "mrta_supervisor.live"} | APPS,
    # an application reaches an architecture only through its registered contract
    "mrta_patrol": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_patrol_murdoch"},
    "mrta_patrol_murdoch": {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor",
                            "mrta_patrol"},  # holds no code at all
    "mrta_delivery": {"mrta_agent.alliance", "mrta_agent.murdoch", "mrta_agent.central",
                      "mrta_agent.ssi", "mrta_agent.cbba", "mrta_agent.tessi",
                      "mrta_delivery_murdoch", "mrta_delivery_tessi",
                      "mrta_delivery_central", "mrta_delivery_ssi", "mrta_delivery_cbba",
                      "mrta_patrol"},
    "mrta_delivery_murdoch": {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor",
                              "mrta_delivery"},  # holds no code at all
    "mrta_delivery_central": {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor",
                              "mrta_delivery"},  # holds no code at all
    "mrta_delivery_ssi": {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor",
                          "mrta_delivery"},  # holds no code at all
    "mrta_delivery_cbba": {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor",
                           "mrta_delivery"},  # holds no code at all
    "mrta_delivery_tessi": {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor",
                            "mrta_delivery"},  # holds no code at all
}
# the top-level import names the wheel installs: none may be another PyPI project's
TOP_LEVEL = {"mrta_zenoh", "mrta_agent", "mrta_simulator", "mrta_supervisor", "mrta_patrol",
             "mrta_patrol_murdoch", "mrta_delivery", "mrta_delivery_murdoch",
             "mrta_delivery_central", "mrta_delivery_ssi", "mrta_delivery_cbba",
             "mrta_delivery_tessi"}


def module_of(path: Path, package: str) -> str:
    rel = path.relative_to(PACKAGES[package]).with_suffix("")
    parts = [p for p in rel.parts if p != "__init__"]
    return ".".join([package, *parts])


def imports_of(path: Path, package: str) -> set[str]:
    """Every module `path` imports, relative imports resolved to absolute names."""
    here = module_of(path, package).split(".")
    if path.name != "__init__.py":
        here = here[:-1]
    out = set()
    for node in source_tree.nodes(path):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = here[:len(here) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            out |= {mod} | {f"{mod}.{a.name}" for a in node.names}
    return out


def hits(imported: set[str], forbidden: set[str]) -> set[str]:
    return {f for f in forbidden for m in imported if m == f or m.startswith(f + ".")}


@pytest.mark.parametrize("package", list(PACKAGES))
def test_no_package_imports_what_it_must_not_know(package):
    bad = []
    for f in source_tree.python_files(PACKAGES[package]):
        hit = hits(imports_of(f, package), FORBIDDEN[package])
        if hit:
            bad.append(f"{f.relative_to(ROOT)} imports {', '.join(sorted(hit))}")
    assert not bad, "\n".join(bad)


# What another room of supervisor/ may reach of a mission. The experiment system: the hook a
# run is resolved with (it starts each run as a `mrta demo` child, never through the runner's
# inside), the summary.json schema it reads back and the parameter overrides it writes into a
# package copy. The live supervisor: the hook alone, to ask an application for its TaskWatch.
REACHES_OF_A_MISSION = {
    "mrta_supervisor.experiment": {"mrta_supervisor.mission", "mrta_supervisor.mission.hook",
                                   "mrta_supervisor.mission.summary",
                                   "mrta_supervisor.mission.overrides"},
    "mrta_supervisor.live": {"mrta_supervisor.mission.hook"},
}


@pytest.mark.parametrize("package", list(REACHES_OF_A_MISSION))
def test_a_room_reaches_missions_only_through_their_entry_points(package):
    modules = {f"mrta_supervisor.mission.{p.stem}"
               for p in PACKAGES["mrta_supervisor.mission"].glob("*.py") if p.name != "__init__.py"}
    bad, reached = [], set()
    for f in sorted(PACKAGES[package].rglob("*.py")):
        for m in imports_of(f, package):
            if m == "mrta_supervisor.mission" or m in modules:
                reached.add(m)
                if m not in REACHES_OF_A_MISSION[package]:
                    bad.append(f"{f.relative_to(ROOT)} imports {m}")
    assert reached and not bad, "\n".join(bad)


def import_circles(package: str) -> list[set[str]]:
    """The circles of `package`'s module import graph (lazy imports included): its strongly
    connected components of more than one module."""
    files = {module_of(f, package): f for f in PACKAGES[package].rglob("*.py")}
    graph = {}
    for name, f in files.items():
        out = set()
        for m in imports_of(f, package):
            while m and m not in files:
                m = m.rpartition(".")[0]
            if m and m not in (name, package):
                out.add(m)
        graph[name] = out
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:  # Tarjan
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            part = {stack.pop()}
            while v not in part:
                part.add(stack.pop())
            if len(part) > 1:
                circles.append(part)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return circles


def test_no_import_circle_runs_through_a_mission_or_the_live_supervisor():
    """The mission hook no longer reaches back: the live supervisor asks the hook for an
    application's TaskWatch (mission/hook.py, application_watch), and the hook imports only the
    TaskWatch type of the live room (live/tasks.py), which imports nothing of a mission."""
    circles = import_circles("mrta_supervisor")
    assert not [c for c in circles
                if any(m.startswith(("mrta_supervisor.mission", "mrta_supervisor.live"))
                       for m in c)], circles
    assert import_circles("mrta_supervisor.mission") == []  # the checker on the room alone


def test_relative_imports_are_resolved():
    """The checker itself: a relative import reaching into a sibling architecture is caught."""
    f = ROOT / "robot_agent" / "alliance" / "agent.py"
    assert "mrta_agent.runtime.loop" in imports_of(f, "mrta_agent.alliance")


def test_the_runtime_holds_no_route_family_module():
    """The route family lives in its own package: no route, own-route or route-message module is
    left in the runtime, and the runtime's names do not mention the route executor."""
    left = sorted(f.name for f in PACKAGES["mrta_agent.runtime"].glob("*.py")
                  if "route" in f.stem)
    assert not left, left
    for f in PACKAGES["mrta_agent.runtime"].glob("*.py"):
        names = {n.name for n in source_tree.nodes(f)
                 if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
        assert not {"RouteArchitecture", "RouteExecutor", "Progress", "Queued"} & names, f


def test_configs_hold_applications_only():
    """No architecture in configs/: every rqt_mrta file there describes an application."""
    for f in (ROOT / "configs").rglob("rqt_mrta.xml"):
        assert "<application>" in f.read_text(encoding="utf-8"), f
    assert not (ROOT / "configs" / "architectures").exists()


def test_the_wheel_installs_only_mrta_import_names():
    text = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
    block = text.split("packages = [", 1)[1].split("]", 1)[0]
    names = {p.strip().strip('"').split(".")[0] for p in block.split(",") if p.strip()}
    assert names == TOP_LEVEL


def test_the_framework_has_no_patrol_specific_code():
    """Not even by name: the agent runtime, the architectures, simulator, supervisor and the
    core never mention the patrol application's plugins, messages or keys (docstrings aside)."""
    bad = []
    for package in ("mrta_zenoh", "mrta_agent.runtime", "mrta_agent.alliance",
                    "mrta_agent.murdoch", "mrta_agent.central", "mrta_simulator",
                    "mrta_supervisor"):
        for f in source_tree.python_files(PACKAGES[package]):
            docstrings = source_tree.docstrings(f)
            for node in source_tree.nodes(f):
                if isinstance(node, ast.Constant) and isinstance(node.value, str) \
                        and id(node) not in docstrings \
                        and any(w in node.value for w in ("patrol_msgs", "patrol/", "wander",
                                                          "border_protection", "patrol")):
                    bad.append(f"{f.relative_to(ROOT)}:{node.lineno}: {node.value[:60]!r}")
    assert not bad, "\n".join(bad)


def _marks_multiprocess(node: ast.AST) -> bool:
    return any(isinstance(n, ast.Attribute) and n.attr == "multiprocess" for n in ast.walk(node))


def whole_file_multiprocess(path: Path) -> bool:
    """Whether every test of the module is marked `multiprocess` (its `pytestmark`, or each
    test function's decorators)."""
    if "multiprocess" not in source_tree.text(path):
        return False  # most modules: no need to parse them
    tree = source_tree.tree(path)
    if any(isinstance(n, ast.Assign) and _marks_multiprocess(n.value)
           and any(isinstance(t, ast.Name) and t.id == "pytestmark" for t in n.targets)
           for n in tree.body):
        return True
    tests = [n for n in tree.body
             if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef)) and n.name.startswith("test_")]
    return bool(tests) and all(any(map(_marks_multiprocess, t.decorator_list)) for t in tests)


def test_no_whole_file_multiprocess_module_sits_at_the_top_of_tests():
    """A module whose every test starts processes or opens real sessions lives in tests/process/
    (tests/README.md), so a maintainer sees from the folder what a module costs to run."""
    top = sorted(f.name for f in (ROOT / "tests").glob("test_*.py") if whole_file_multiprocess(f))
    assert top == []
    assert all(whole_file_multiprocess(f) for f in (ROOT / "tests" / "process").glob("test_*.py"))
