"""The README's instance walkthrough (its "Instances" section) as a newcomer follows it (issue
51, the newcomer's list): its commands run as written; the demo's --duration reaches the last
arrival of the instance it generates (a 60 s run of it delivered 3/20 and nothing said why);
a run that ends before tasks arrive says so; and the run's files are listed by kind, with
ALLIANCE's motivation panels drawn only where a robot was active (258 pictures and a one-line
list of 261 names before)."""

from __future__ import annotations

import shlex
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import Motivation
from mrta_delivery.generate import load_instance
from mrta_delivery.metrics import arrivals
from mrta_delivery.mission import DELIVERY
from mrta_supervisor.mission.cli import files_line
from mrta_zenoh.cli.main import cli
from mrta_zenoh.codec import encode, encoding_for
from mrta_zenoh.messages import Header
from tests.harness.helpers import ROOT
from tests.test_generators_valid import solomon_text


def walkthrough() -> list[list[str]]:
    """The `mrta …` lines of the first code block after "## Instances" (argv after `mrta`;
    a trailing comment and an optional `[...]` dropped)."""
    text = (ROOT / "README.md").read_text().split("\n## Instances\n", 1)[1]
    block = text.split("```\n", 2)[1]
    out = []
    for line in block.splitlines():
        line = line.split("  #")[0]
        words = [w for w in shlex.split(line) if not w.startswith("[") and not w.endswith("]")]
        assert words[0] == "mrta", line
        out.append(words[1:])
    return out


def option(argv: list[str], name: str) -> str:
    return argv[argv.index(name) + 1]


def test_the_readme_instance_commands_write_valid_instances_a_run_of_its_duration_serves(
        tmp_path, monkeypatch):
    """generate (delivery, windows, Solomon on a small file of that format) and validate as the
    README has them; its demo line's --duration passes the generated instance's last arrival."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "C101.txt").write_text(solomon_text(  # 12 customers, as --tasks 10 needs
        (40, 50), [(10 + 7 * k, 20 + (k * 37) % 60, 10 * k) for k in range(12)]))
    lines = walkthrough()
    verbs = [a[0] if a[0] == "demo" else " ".join(a[:2]) for a in lines]
    assert verbs == ["instance generate"] * 3 + ["instance validate", "instance show", "demo",
                                                 "demo"], verbs
    for argv in lines[:4]:
        r = CliRunner().invoke(cli, argv)
        assert r.exit_code == 0, (argv, r.output)
    inst = yaml.safe_load((tmp_path / option(lines[0], "-o")).read_text())
    last = max(t.get("arrival", 0.0) for t in inst["tasks"].values())
    demo = lines[5]
    assert option(demo, "--instance") == option(lines[0], "-o")
    assert last > 60.0  # the default --duration: why the README gives one
    assert float(option(demo, "--duration")) > last


def test_a_run_ending_before_tasks_arrive_says_how_many_and_when_the_last_comes():
    problem = load_instance().problem()
    every = arrivals(problem, 60.0)
    assert every == {"arrived": 4, "last_arrival": max(t.arrival for t in problem.tasks)}
    late = [t for t in problem.tasks if t.arrival > 0]
    metrics = {"completed": 1, "tasks": 4, "makespan": None, "objective": "minsum",
               "arrived": 1, "last_arrival": 198.25}
    said = DELIVERY.describe(metrics)
    assert "3 of 4 tasks arrive after the run's end (the last at 198.25 s)" in said[1]
    assert len(DELIVERY.describe({**metrics, "arrived": 4})) == 1
    assert late == [] or arrivals(problem, min(t.arrival for t in late) - 1.0)["arrived"] < 4


def test_the_files_line_counts_a_kind_of_many_files():
    many = [f"motivation_robot{i}_t{j}.png" for i in range(1, 21) for j in range(1, 14)]
    got = files_line(sorted(many + ["run.mcap", "summary.json", "timeline.png", "world.png"]))
    assert got == "260 × motivation_*.png, run.mcap, summary.json, timeline.png, world.png"
    few = ["motivation_robot1_wander.png", "run.mcap", "summary.json"]
    assert files_line(few) == ", ".join(few)


def motivation(robot: str, task: str, at: float, active: bool) -> tuple:
    m = Motivation(Header(robot, at, int(at * 10)), task, 0.0, False, False, False, True,
                   50.0 if active else 10.0, 40.0, active)
    return (ALLIANCE.key(robot, "motivation", task), encoding_for(m.TYPE_NAME),
            int(at * 1e9), encode(m))


def test_alliance_draws_the_motivations_of_the_tasks_a_robot_was_active_on(tmp_path,
                                                                          monkeypatch):
    """Which pairs are drawn (the drawing itself: tests/process/test_patrol_system.py)."""
    from mrta_agent.alliance import plots
    drawn = []
    monkeypatch.setattr(plots, "draw_motivation", lambda rows, tb, robot, task, f: (
        drawn.append((robot, task, [m.active for _, m in rows])), f.write_bytes(b"")))
    records = [motivation("robot1", "t1", 0.1 * k, active=k >= 3) for k in range(6)]
    records += [motivation("robot1", "t2", 0.1 * k, active=False) for k in range(6)]
    records += [motivation("robot2", "t2", 0.1 * k, active=k == 5) for k in range(6)]
    written = ALLIANCE.plots(Path("run.mcap"), ["robot1", "robot2"], ["t1", "t2"], tmp_path,
                             records)
    assert written == ["motivation_robot1_t1.png", "motivation_robot2_t2.png"]
    assert sorted(p.name for p in tmp_path.iterdir()) == written
    assert drawn == [("robot1", "t1", [False] * 3 + [True] * 3),
                     ("robot2", "t2", [False] * 5 + [True])]


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(2700)
def test_the_readme_instance_walkthrough_runs_as_written(children, tmp_path):
    """show, then the demo line as written (at --speed 0, without pictures): every task of the
    generated instance delivered before the README's --duration. The run is ≈ 450 CPU-s with
    a process per robot (measured: 21 min of wall time at load ≈ 50); 800 s of wall time was
    too little for it beside load 20–25, so the bounds are a guard against a hang, not a
    figure."""
    import json
    lines = walkthrough()
    inst = tmp_path / option(lines[0], "-o")
    assert CliRunner().invoke(cli, [*lines[0][:-1], str(inst)]).exit_code == 0
    show = children.mrta("instance", "show", str(inst), name="show")
    assert show.wait(300) == 0, show.tail(20)
    assert any(line.startswith("last_arrival:") for line in show.stdout), show.tail(30)
    demo = lines[5]
    out = tmp_path / "demo-output"
    run = children.mrta(*[str(inst) if a == option(demo, "--instance") else a for a in demo],
                        "--speed", "0", "--no-live", "--no-plots", "--agents-per-process", "10",
                        "--output", str(out), name="demo")
    assert run.wait(2400) == 0, run.tail(30)
    m = json.loads((out / "summary.json").read_text())["metrics"]
    assert m["arrived"] == m["tasks"] == 20
    assert m["completed"] == 20, m
