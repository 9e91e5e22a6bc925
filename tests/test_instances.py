"""Instances as run input, in process: `mrta instance generate | show | validate` (click's
runner on the real root command), the delivery generator (byte-for-byte reproducible, its own
seed stream, points clear of walls, Poisson arrivals), Solomon files through vrplib (a small
file written here, its mapping recomputed here), bad files (exit 2 naming file, line and key),
the summary's section read back as the same instance, and the derived packages."""

from __future__ import annotations

import json
import math
import re

import pytest
from click.testing import CliRunner

from mrta_delivery.generate import derive
from mrta_delivery.instance import load_document
from mrta_delivery.instances import CLEARANCE, DeliveryGeneratorParams, generate_document
from mrta_delivery.metrics import instance_json
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from tests.test_planning_reference import brute_force


def mrta(*args: str):
    return CliRunner().invoke(cli, list(args), catch_exceptions=False)


def generated(tmp_path, name: str, *args: str):
    out = tmp_path / name
    r = mrta("instance", "generate", "delivery", *args, "-o", str(out))
    assert r.exit_code == 0, r.output
    return out


def test_the_same_generator_parameters_and_seed_give_the_same_file_byte_for_byte(tmp_path):
    args = ("--robots", "20", "--tasks", "20", "--walls", "2", "--rate", "0.1", "--seed", "7")
    a, b = generated(tmp_path, "a.yaml", *args), generated(tmp_path, "b.yaml", *args)
    assert a.read_bytes() == b.read_bytes()
    c = generated(tmp_path, "c.yaml", *args[:-1], "8")
    assert c.read_bytes() != a.read_bytes()
    doc = load_document(a)
    assert doc.name == "delivery-r20-t20-w2-7"  # generator, sizes, walls and seed: never a path
    assert (len(doc.robots), len(doc.tasks), len(doc.world.walls)) == (20, 20, 2)
    # to standard output when no file is named: the same text
    assert mrta("instance", "generate", "delivery", *args).output == a.read_text()


def seg_dist(p, w) -> float:
    x1, y1, x2, y2 = w
    t = max(0.0, min(1.0, ((p[0] - x1) * (x2 - x1) + (p[1] - y1) * (y2 - y1))
                     / ((x2 - x1) ** 2 + (y2 - y1) ** 2)))
    return math.hypot(p[0] - x1 - t * (x2 - x1), p[1] - y1 - t * (y2 - y1))


@pytest.mark.parametrize("seed", range(4))
def test_generated_points_are_in_the_room_clear_of_walls_and_arrivals_are_poisson(seed):
    p = DeliveryGeneratorParams(robots=6, tasks=60, walls=3, rate=0.5, room=(14.0, 9.0),
                                speeds=(0.3, 0.6), capabilities="lift:0.3")
    doc = generate_document(p, seed)
    room = [(-7, -4.5, 7, -4.5), (7, -4.5, 7, 4.5), (7, 4.5, -7, 4.5), (-7, 4.5, -7, -4.5)]
    walls = room + [tuple(w) for w in doc.world.walls]
    points = [r.start for r in doc.robots.values()] + [t.position for t in doc.tasks.values()]
    for pt in points:
        assert min(seg_dist(pt, w) for w in walls) > CLEARANCE
    for r in doc.robots.values():
        assert 0.3 <= r.speed <= 0.6
    assert doc.robots["robot1"].capabilities == ("lift",)
    arrivals = [t.arrival for t in doc.tasks.values()]
    assert arrivals == sorted(arrivals) and arrivals[0] > 0
    gaps = [b - a for a, b in zip([0.0] + arrivals, arrivals)]
    assert 1.0 < sum(gaps) / len(gaps) * 0.5 * 2 < 3.0  # mean gap ≈ 1 / rate = 2 s
    needs = [t.capability for t in doc.tasks.values()]
    assert set(needs) <= {"", "lift"} and 0 < needs.count("lift") < 60


@pytest.mark.slow
def test_show_gives_sizes_costs_and_the_optimum_brute_force_agrees_with(tmp_path):
    f = generated(tmp_path, "i.yaml", "--robots", "2", "--tasks", "4", "--walls", "1",
                  "--seed", "3")
    r = mrta("instance", "show", str(f), "--json")
    assert r.exit_code == 0, r.output
    info = json.loads(r.output)
    assert (info["name"], info["robots"], info["tasks"]) == ("delivery-r2-t4-w1-3", 2, 4)
    problem = load_document(f).problem()
    for objective in ("minsum", "makespan", "flowtime"):
        ref = info["reference"][objective]
        assert ref["label"] == "optimal" and ref["method"] == "exact"
        assert ref["value"] == pytest.approx(brute_force(problem, objective), abs=1e-3)
    text = mrta("instance", "show", str(f)).output
    assert "makespan: value:" in text and "label: optimal" in text
    r = mrta("instance", "show", str(f), "--exact-limit", "0", "--json")
    assert all(v["label"] == "best found" for v in json.loads(r.output)["reference"].values())


BAD = [
    ("robots:\n  robot1: {start: [0, 0], sped: 0.5}\n", 2, "robots/robot1/sped",
     "unknown key 'sped' (did you mean 'speed'?)"),
    ("robots:\n  robot1: {start: [0, 0], speed: 0.5}\ntasks:\n  t1: {position: [1, x]}\n", 4,
     "tasks/t1/position/1", "Expected float, got str"),
    ("robots:\n  robot1: {start: [0, 0], speed: 0.5}\ntasks:\n  t1: {position: [1, 1],"
     " capability: lift}\n", 4, "tasks/t1/capability", "no robot has capability 'lift'"),
    ("robots:\n  robot1: {start: [0, 0], speed: 0.5}\ntasks:\n  t1: {position: [2, 0.1]}\n"
     "world: {size: [12, 8], walls: [[2, -1, 2, 1]]}\n", 4, "tasks/t1/position",
     "closer than 0.4 m"),
    ("robots:\n  robot1: {start: [0, 0], speed: 0.5}\ntasks:\n  t1: {position: [7, 0]}\n", 4,
     "tasks/t1/position", "outside the 12 × 8 m room"),
    ("robot:\n  robot1: {start: [0, 0], speed: 0.5}\n", 1, "robot",
     "unknown key 'robot' (did you mean 'robots'?)"),
]


@pytest.mark.parametrize("text, line, key, message", BAD)
def test_a_bad_instance_exits_2_naming_file_line_and_key(tmp_path, text, line, key, message):
    f = tmp_path / "bad.yaml"
    f.write_text(text)
    r = CliRunner().invoke(cli, ["instance", "validate", str(f)])
    assert r.exit_code == 2
    first = r.output.strip().splitlines()
    assert len(first) == 1 and "Traceback" not in r.output
    assert re.search(rf"{re.escape(str(f))}:{line}: '{re.escape(key)}': .*{re.escape(message)}",
                     first[0]), first[0]


@pytest.mark.slow
def test_a_bad_instance_given_to_demo_exits_2_before_anything_starts(tmp_path):
    f = tmp_path / "bad.yaml"
    f.write_text(BAD[0][0])
    r = CliRunner().invoke(cli, ["demo", "--application", "delivery", "--instance", str(f),
                                 "--output", str(tmp_path / "out"), "--no-live"])
    assert r.exit_code == 2
    assert f"{f}:2: 'robots/robot1/sped'" in r.output
    assert not (tmp_path / "out" / "instance").exists()
    r = CliRunner().invoke(cli, ["demo", "--application", "patrol", "--instance",
                                 str(generated(tmp_path, "ok.yaml")), "--output",
                                 str(tmp_path / "out2"), "--no-live"])
    assert r.exit_code == 2 and "the patrol mission takes no --instance" in r.output


def test_the_summary_section_reads_back_as_the_same_instance(tmp_path):
    f = generated(tmp_path, "i.yaml", "--robots", "3", "--tasks", "4", "--walls", "1",
                  "--rate", "0.2", "--seed", "1")
    doc = load_document(f)
    section = instance_json(doc.body(), doc.problem())
    assert len(section["cost"]) == 3 and "around the walls" in section["cost_model"]
    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps({"mission": "delivery", "robots": ["x"], "instance": section}))
    again = load_document(summary)
    assert again.body() == doc.body() and again.name == doc.name
    alone = tmp_path / "section.json"
    alone.write_text(json.dumps(section))
    assert load_document(alone).body() == doc.body()


def test_derived_packages_carry_the_instance_and_its_world(tmp_path):
    f = generated(tmp_path, "i.yaml", "--robots", "4", "--tasks", "3", "--walls", "1",
                  "--seed", "4")
    doc = load_document(f)
    folder = tmp_path / "run" / "instance"
    derive(doc, folder)
    for pkg, stem in (("delivery", "alliance"), ("delivery_murdoch", "murdoch"),
                      ("delivery_central", "central"), ("delivery_ssi", "ssi"),
                      ("delivery_cbba", "cbba")):
        launch = (folder / pkg / "launch" / "delivery_sim.launch").read_text()
        assert launch.count('<arg name="robot_id"') == 4  # one agent per robot of the instance
        assert "--robot robot4=" in launch
        assert instance_named_by_layers(folder / pkg / "config" /
                                        f"layers_{stem}_params.yaml") == doc.body()
    world = (folder / "delivery" / "worlds" / "delivery.yaml").read_text()
    assert f"segment: {list(doc.world.walls[0])}".replace("(", "[") in world
    # all or nothing: a bad instance leaves the folder as it was
    bad = doc.body()
    with pytest.raises(ConfigError):
        derive(type(doc)(robots={}, tasks=bad.tasks, world=bad.world), folder)
    assert (folder / "delivery" / "worlds" / "delivery.yaml").read_text() == world


def test_a_run_derives_only_the_packages_its_architecture_reads(tmp_path):
    """`mrta demo --instance` under CBBA writes `delivery` (the application, its world) and
    `delivery_cbba`, the very files the full derivation writes for them, and nothing else."""
    from mrta_delivery.generate import all_files, run_files
    f = generated(tmp_path, "i.yaml", "--robots", "3", "--tasks", "4", "--seed", "2")
    body = load_document(f).body()
    every = all_files(body)
    for arch, packages in (("cbba", {"delivery", "delivery_cbba"}), ("alliance", {"delivery"}),
                           ("central", {"delivery", "delivery_central"})):
        files = run_files(body, arch)
        assert {rel.split("/", 1)[0] for rel in files} == packages
        assert files == {rel: data for rel, data in every.items()
                         if rel.split("/", 1)[0] in packages}
    with pytest.raises(ConfigError, match="no package for architecture 'nope'"):
        run_files(body, "nope")


def instance_named_by_layers(path):
    from mrta_agent.runtime.instance import named_instance
    from mrta_agent.runtime.params import load_layers_params
    return load_document(named_instance(load_layers_params(path))).body()


SOLOMON = """C1MINI

VEHICLE
NUMBER     CAPACITY
  25         200

CUSTOMER
CUST NO.  XCOORD.   YCOORD.    DEMAND   READY TIME  DUE DATE   SERVICE   TIME

    0      40         50          0          0       1236          0
    1      45         68         10        912        967         90
    2      30         70         30        825        870         90
    3      60         56         10         65        146         90
    4      20         30         20          0        300         10
"""


def test_a_solomon_file_maps_depot_customers_times_and_scale(tmp_path):
    src = tmp_path / "c1mini.txt"
    src.write_text(SOLOMON)
    out = tmp_path / "s.yaml"
    r = mrta("instance", "generate", "solomon", "--file", str(src), "--robots", "2",
             "--tasks", "3", "--speed", "0.5", "-o", str(out))
    assert r.exit_code == 0, r.output
    doc = load_document(out)
    # the points used: depot (40, 50) and customers 1-3; box x 30..60, y 50..70
    scale = min((12 - 2) / 30, (8 - 2) / 20)          # 0.3 m per unit: the height binds
    cx, cy = 45.0, 60.0
    assert doc.robots["robot1"].start == pytest.approx(((40 - cx) * scale, (50 - cy) * scale))
    assert math.dist(doc.robots["robot2"].start, doc.robots["robot1"].start) >= 1.0 - 1e-9
    assert list(doc.tasks) == ["c1", "c2", "c3"]
    per_unit = scale / 0.5                            # s per Solomon time unit
    c3 = doc.tasks["c3"]
    assert c3.position == pytest.approx(((60 - cx) * scale, (56 - cy) * scale))
    # ready time → earliest on a task known from the start; due date → due
    assert (c3.arrival, c3.earliest, c3.service, c3.due) == pytest.approx(
        (0.0, 65 * per_unit, 90 * per_unit, 146 * per_unit))
    assert doc.windows == "hard"
    assert all(r.speed == 0.5 and r.capabilities == () for r in doc.robots.values())
    assert doc.name == "C1MINI-r2-t3"
    # the travel model keeps Solomon's times: a robot covers one unit in one (scaled) unit
    p = doc.problem()
    assert p.travel(0, 0, 1) == pytest.approx(math.dist((45, 68), (30, 70)) * per_unit)
    online = tmp_path / "online.yaml"                 # today's arrival mapping, kept
    r = mrta("instance", "generate", "solomon", "--file", str(src), "--robots", "2",
             "--tasks", "3", "--speed", "0.5", "--ready", "arrival", "--windows", "soft",
             "-o", str(online))
    assert r.exit_code == 0, r.output
    c3 = load_document(online).tasks["c3"]
    assert (c3.arrival, c3.earliest, c3.due) == pytest.approx((65 * per_unit, None,
                                                               146 * per_unit))
    assert load_document(online).windows == "soft"
    assert load_document(online).name == "C1MINI-r2-t3-online"
    bad = tmp_path / "bad.txt"
    bad.write_text("not a solomon file\n")
    r = CliRunner().invoke(cli, ["instance", "generate", "solomon", "--file", str(bad)])
    assert r.exit_code == 2 and str(bad) in r.output and "Solomon" in r.output


@pytest.mark.parametrize("args, message", [
    (("--speeds", "0.7", "0.3"), "--speeds 0.7 0.3"),
    (("--speeds", "0.001", "0.3"), "0.01 ≤ MIN"),
    (("--capabilities", "lift:0.8,cold:0.5"), "sum to more than 1"),
    (("--capabilities", "lift"), "'lift' is not NAME:P"),
    (("--walls", "30", "--room", "4", "4"), "could not place wall"),
    (("--robots", "100", "--room", "3", "3"), "could not place robot"),
    (("--robots", "0"), "--robots 0: Expected int >= 1"),  # the flag, not msgspec's `$.robots`
    (("--tasks", "0"), "--tasks 0: Expected int >= 1"),
])
def test_bad_generator_parameters_exit_2_in_one_line(tmp_path, args, message):
    out = tmp_path / "x.yaml"
    r = CliRunner().invoke(cli, ["instance", "generate", "delivery", *args, "-o", str(out)])
    assert r.exit_code == 2 and message in r.output, r.output
    assert len(r.output.strip().splitlines()) == 1 and not out.exists()


@pytest.mark.parametrize("option", ["--robots", "--tasks"])
def test_an_instance_of_no_robot_or_no_task_is_refused(tmp_path, option):
    """An instance without a robot or a task is no problem to allocate: exit 2, nothing
    written."""
    out = tmp_path / "i.yaml"
    r = CliRunner().invoke(cli, ["instance", "generate", "delivery", option, "0", "-o", str(out)])
    assert r.exit_code == 2 and ">= 1" in r.output and not out.exists()
