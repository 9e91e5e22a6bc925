"""`mrta experiment` over instances and architectures, for real: 2 generated instances × ALLIANCE
and MURDOCH × 1 seed, with faults that name robots by role, run twice — the same rows but wall
time; `@random` the same robot for an instance under both architectures, `@first` the robot the
robots' own reports show first on a task (the summary's who_did_what, read here, not the
announcements the agents resolved it from), and that robot stood still from the stall on; the
rows' reference values are each instance's optimum, found here by brute force."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

STALL_AT, CRASH_AT = 3.0, 6.0
EXPERIMENT = f"""\
application: delivery
duration: 14
seeds: [1]
architectures: [alliance, murdoch]
failures: ["stall:@first@{STALL_AT:g},crash:@random@{CRASH_AT:g}"]
instances:
  generator: delivery
  parameters: {{capabilities: ""}}
  robots: [3]
  count: 2
  seed: 21
"""
WALL = ("wall_seconds",)  # the machine's: the one column two runs may differ in


def rows(folder: Path) -> list[dict]:
    return list(csv.DictReader((folder / "results.csv").open()))


def natural(robot: str) -> tuple:
    import re
    return tuple(int(p) if p.isdigit() else p for p in re.split(r"(\d+)", robot))


def first_on_a_task(summary: dict, before: float, named: set[str]) -> str | None:
    """The robot whose first interval on any task began earliest before `before` (ties: the
    lower id, robot2 before robot10), from the robots' own reports, among those no other item
    of the spec names."""
    starts = [(min(s["from"] for s in spans), natural(r), r)
              for r, spans in summary["who_did_what"].items() if spans and r not in named]
    starts = [s for s in starts if s[0] < before]
    return min(starts)[2] if starts else None


def poses(run: Path, robot: str) -> list[tuple[float, float, float]]:
    """(stamp, x, y) of the robot's ground truth, from the recording."""
    from mrta_zenoh.codec import decode, type_from_encoding
    from mrta_zenoh.recording import read_recording
    out = []
    for key, enc, _t, payload in read_recording(run / "run.mcap"):
        if key == f"{robot}/ground_truth":
            m = decode(type_from_encoding(enc), payload)
            out.append((m.header.stamp, m.pose.x, m.pose.y))
    return out


@pytest.mark.timeout(1800)
def test_the_same_file_twice_gives_the_same_rows_and_roles_resolve_the_same(children,
                                                                            tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text(EXPERIMENT)
    got = {}
    for name in ("a", "b"):
        exp = children.mrta("experiment", f, "--output", tmp_path / name, "--jobs", "2",
                            "--no-plots", name=f"experiment {name}")
        assert exp.wait(900) == 0, exp.tail(30)
        got[name] = rows(tmp_path / name)
    a, b = got["a"], got["b"]
    assert len(a) == 4 and [r["status"] for r in a] == ["ok"] * 4, a
    assert list(a[0]) == list(b[0])  # the same columns, in the same order
    strip = [{k: v for k, v in r.items() if k not in WALL} for r in a]
    assert strip == [{k: v for k, v in r.items() if k not in WALL} for r in b]
    # the instances were made once, the same bytes each time (instances/references/ beside
    # them caches their solved references: a search its time cap cut short may differ there,
    # mrta_zenoh/planning/reference.py, so they are not compared)
    made = sorted(p for p in (tmp_path / "a" / "instances").iterdir() if p.is_file())
    assert made
    for inst in made:
        assert inst.read_bytes() == (tmp_path / "b" / "instances" / inst.name).read_bytes()
    random_robot: dict[str, set[str]] = {}
    for r in a:
        s = json.loads((tmp_path / "a" / f"run{int(r['run']):03d}" / "summary.json").read_text())
        # @random: drawn from the instance, so the same robot under either architecture
        crash = next(i for i in s["faults"].split(",") if i.startswith("crash:"))
        drawn = crash.split(":")[1].split("@")[0]
        random_robot.setdefault(r["instance"], set()).add(drawn)
        # @first: the robot the robots' own reports show first on a task before the stall,
        # among the others
        first = first_on_a_task(s, STALL_AT, {drawn})
        assert first is not None and s["failure"]["robot"] == first == r["failed_robot"], s
        assert s["failure"]["role"] == "@first" and s["failure"]["fault"] == "stall"
        # … and the agent that stalled is that robot: it stood still from then on
        run = tmp_path / "a" / f"run{int(r['run']):03d}"
        late = [(x, y) for t, x, y in poses(run, first) if t >= STALL_AT + 1.0]
        assert late and max(math.dist(late[0], p) for p in late) < 0.01, first
    assert all(len(v) == 1 for v in random_robot.values()), random_robot
    # the reference value of each objective, from the instance file: brute force here
    from mrta_delivery.instance import load_document
    from tests.test_planning_reference import brute_force
    for r in a:
        problem = load_document(tmp_path / "a" / "instances" / f"{r['instance']}.yaml").problem()
        for objective in ("minsum", "makespan", "flowtime"):
            assert float(r[f"metrics.reference_{objective}"]) == \
                pytest.approx(brute_force(problem, objective), abs=1e-3), (objective, r)
        assert r["metrics.reference_proven_optimal"] == "True"
