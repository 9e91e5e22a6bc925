"""Bounded instances (issue 51.5): an instance's sizes are capped in its schema (robots, tasks,
inner walls), and `mrta instance validate` refuses — one line, exit 2, naming the cap or the
key — what every run would refuse: ids that are not one key chunk, a `max_tasks_per_robot`
that leaves a task without a capable robot with room. `mrta instance show` refuses the same
files the same way (no MemoryError building a matrix)."""

from __future__ import annotations

import re

import pytest
from click.testing import CliRunner

from mrta_delivery.instance import MAX_ROBOTS, MAX_TASKS, MAX_WALLS
from mrta_zenoh.cli.main import cli

HEAD = "application: delivery\n"
ONE_ROBOT = "robots:\n  robot1: {start: [0.5, 0.5], speed: 0.5}\n"
ONE_TASK = "tasks:\n  t1: {position: [3.5, 3.0]}\n"


def refused(tmp_path, text: str, *verb: str) -> str:
    f = tmp_path / "i.yaml"
    f.write_text(text)
    r = CliRunner().invoke(cli, ["instance", *(verb or ("validate",)), str(f)])
    lines = r.output.strip().splitlines()
    assert r.exit_code == 2, r.output
    assert len(lines) == 1 and "Traceback" not in r.output, r.output
    assert lines[0].startswith(f"Error: {f}:"), lines[0]
    return lines[0]


def walls(n: int) -> str:
    rows = "".join(f"    - [{-150 + 3 * k}, 100, {-149 + 3 * k}, 101]\n" for k in range(n))
    return HEAD + ONE_ROBOT + ONE_TASK + "world:\n  size: [400, 400]\n  walls:\n" + rows


@pytest.mark.parametrize("verb", [("validate",), ("show", "--json")])
def test_too_many_walls_tasks_or_robots_are_refused_naming_the_cap(tmp_path, verb):
    line = refused(tmp_path, walls(MAX_WALLS + 250), *verb)
    assert f"'world/walls': {MAX_WALLS + 250} inner walls: an instance has at most " \
           f"{MAX_WALLS} (MAX_WALLS" in line
    tasks = "".join(f"  t{k}: {{position: [{-5 + k % 10}, {-3 + k // 10 % 6}]}}\n"
                    for k in range(MAX_TASKS + 1))
    line = refused(tmp_path, HEAD + ONE_ROBOT + "tasks:\n" + tasks, *verb)
    assert f"'tasks': {MAX_TASKS + 1} tasks: an instance has at most {MAX_TASKS} (MAX_TASKS" \
           in line
    robots = "".join(f"  r{k}: {{start: [0, 0], speed: 1}}\n" for k in range(MAX_ROBOTS + 1))
    line = refused(tmp_path, HEAD + "robots:\n" + robots + ONE_TASK, *verb)
    assert f"at most {MAX_ROBOTS} (MAX_ROBOTS" in line


def test_at_the_cap_an_instance_is_accepted(tmp_path):
    f = tmp_path / "i.yaml"
    f.write_text(walls(MAX_WALLS))
    r = CliRunner().invoke(cli, ["instance", "validate", str(f)])
    assert r.exit_code == 0, r.output


@pytest.mark.parametrize("text, key", [
    (HEAD + "robots:\n  robot 1: {start: [0.5, 0.5], speed: 0.5}\n" + ONE_TASK, "robots/robot 1"),
    (HEAD + ONE_ROBOT + "tasks:\n  t/1: {position: [3.5, 3.0]}\n", "tasks/t/1"),
    (HEAD + ONE_ROBOT + "tasks:\n  '*': {position: [3.5, 3.0]}\n", "tasks/*"),
])
def test_an_id_that_is_not_one_key_chunk_is_refused(tmp_path, text, key):
    line = refused(tmp_path, text)
    assert re.search(rf"'{re.escape(key)}': \w+ id .* is not one key chunk", line), line


CAPACITY = HEAD + """max_tasks_per_robot: {cap}
robots:
  robot1: {{start: [0.5, 0.5], speed: 0.5, capabilities: [lift]}}
  robot2: {{start: [-2.5, 0.5], speed: 0.5}}
tasks:
  t1: {{position: [3.5, 3.0], capability: lift}}
  t2: {{position: [-3.5, 3.0], capability: lift}}
  t3: {{position: [1.5, -3.0]}}
"""


def test_a_capacity_too_small_for_every_task_is_refused(tmp_path):
    # three tasks, two robots of one task each: one task left over
    line = refused(tmp_path, CAPACITY.format(cap=1))
    assert "'max_tasks_per_robot': 1 tasks per robot leaves 1 of 3 tasks" in line
    # enough places in all (2 × 2 ≥ 3), but both lift tasks need robot1: only by its capability
    # is the capacity too small — still refused
    line = refused(tmp_path, CAPACITY.format(cap=1).replace("t3: {position: [1.5, -3.0]}",
                                                            "t3: {position: [1.5, -3.0]}\n"
                                                            "  t4: {position: [1.5, 3.0]}"))
    assert "leaves 2 of 4 tasks" in line
    f = tmp_path / "ok.yaml"
    f.write_text(CAPACITY.format(cap=2))
    assert CliRunner().invoke(cli, ["instance", "validate", str(f)]).exit_code == 0


def test_a_task_walled_in_is_refused_as_every_run_would_refuse_it(tmp_path):
    box = "[[2, 1, 4, 1], [4, 1, 4, 3], [4, 3, 2, 3], [2, 3, 2, 1]]"
    text = (HEAD + ONE_ROBOT + "tasks:\n  t1: {position: [-3.5, 3.0]}\n  t2: {position: [3, 2]}\n"
            f"world: {{size: [12, 8], walls: {box}}}\n")
    line = refused(tmp_path, text)
    assert ":6: 'tasks/t2/position': task t2 at (3, 2) cannot be reached from robot robot1" in line


def test_show_and_a_run_compare_with_one_best_found(tmp_path):
    """One instance, one "best found" (issue 51): `mrta instance show` searched 1,000 solutions
    and a run's summary 200, so the two printed different references for the same instance.
    Above the exact limit, show's default value is the run's (objectives.references)."""
    import json

    from mrta_delivery.instance import load_document
    from mrta_delivery.objectives import references
    from mrta_zenoh.planning.reference import EXACT_LIMIT

    tasks = "".join(f"  t{k}: {{position: [{-5 + k % 10}.5, {-3 + 2 * (k // 10)}.5]}}\n"
                    for k in range(EXACT_LIMIT + 1))
    f = tmp_path / "i.yaml"
    f.write_text(HEAD + "robots:\n  robot1: {start: [0, 0], speed: 0.5}\n"
                 "  robot2: {start: [1, 0], speed: 0.4}\ntasks:\n" + tasks)
    r = CliRunner().invoke(cli, ["instance", "show", str(f), "--json"])
    assert r.exit_code == 0, r.output
    shown = json.loads(r.output)["reference"]["minsum"]
    run = references(load_document(f).problem())["minsum"]
    assert shown["label"] == "best found" and not shown.get("stopped_by_time_limit")
    assert shown["value"] == round(run["value"], 3)


def test_a_demo_refused_for_its_instance_leaves_no_output_folder(tmp_path):
    """A refused command leaves no empty output folder behind (issue 51, the newcomer's list)."""
    f = tmp_path / "i.yaml"
    f.write_text(CAPACITY.format(cap=1))
    out = tmp_path / "out"
    r = CliRunner().invoke(cli, ["demo", "--application", "delivery", "--instance", str(f),
                                 "--output", str(out), "--no-live"])
    assert r.exit_code == 2 and "max_tasks_per_robot" in r.output, r.output
    assert not out.exists()
    out.mkdir()  # a folder that was there stays
    r = CliRunner().invoke(cli, ["demo", "--application", "delivery", "--instance", str(f),
                                 "--output", str(out), "--no-live"])
    assert r.exit_code == 2 and out.is_dir()
