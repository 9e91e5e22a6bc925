"""World files: the original MobileSim maps, our YAML format, and what a bad file gets told."""

import numpy as np
import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_simulator.api import parse_robot, place_robots
from mrta_simulator.world import Pose, load_world
from tests.harness.helpers import PATROL_WORLD, REFERENCE

MAPS = {"map1.map": (12, 3), "map2.map": (32, 11), "map3.map": (25, 0), "office.map": (101, 1)}


@pytest.mark.parametrize("name", sorted(MAPS))
def test_every_reference_map_loads(reference, name):
    world = load_world(REFERENCE / "alliance_test" / "map" / name)
    lines, homes = MAPS[name]
    assert world.walls.shape == (lines, 4)
    assert len(world.starts) == homes
    assert any("DATA" in n for n in world.notes)  # skipped sections are reported, not hidden


def test_map3_is_the_44_by_14_metre_patrol_world(reference):
    world = load_world(REFERENCE / "alliance_test" / "map" / "map3.map")
    xmin, ymin, xmax, ymax = world.bounds
    assert xmax - xmin == pytest.approx(44.077) and ymax - ymin == pytest.approx(14.041)
    assert world.walls[0].tolist() == [-19.95, -8.067, 24.081, -8.067]  # millimetres → metres


def test_yaml_world_with_segments_polygons_starts_and_border(tmp_path):
    f = tmp_path / "w.yaml"
    f.write_text("name: t\nwalls:\n  - segment: [0, 0, 1, 0]\n"
                 "  - polygon: [[0, 0], [2, 0], [2, 2]]\n  - polyline: [[5, 5], [6, 5], [6, 6]]\n"
                 "robots:\n  r1: [1, 2, 90]\nborder: [[0, 0], [2, 0], [2, 2]]\n")
    w = load_world(f)
    assert len(w.walls) == 1 + 3 + 2
    assert w.starts["r1"] == Pose(1.0, 2.0, np.pi / 2)
    assert w.border_segments().shape == (3, 4)


def test_bundled_patrol_world_loads():
    w = load_world(PATROL_WORLD)
    assert {"robot1", "robot2", "robot3"} <= set(w.starts) and w.border is not None


BAD = [
    ("bad.map", "2D-Map\nLINES\n0 0 1000\n", 3, "needs 4 numbers"),
    ("bad.map", "2D-Map\nLINES\n0 0 1000 x\n", 3, "must be finite numbers"),
    ("bad.map", "hello\n", 1, "2D-Map"),
    ("bad.map", "2D-Map\nNumLines: 3\nLINES\n0 0 1000 0\nDATA\n", 2, "NumLines says 3"),
    ("bad.map", "2D-Map\nCairn: RobotHome 1 x 0 \"\" ICON \"\"\nLINES\n", 2, "RobotHome needs"),
    ("bad.yaml", "walls:\n  - segmnet: [0, 0, 1, 1]\n", 2, "did you mean 'segment'"),
    ("bad.yaml", "walls:\n  - segment: [0, 0, 1]\n", 2, "list of 4 numbers"),
    ("bad.yaml", "wals: []\n", 1, "did you mean 'walls'"),
    ("bad.yaml", "walls:\n  - polygon: [[0, 0], [1, 1]]\n", 2, "at least 3"),
    ("bad.yaml", "walls: []\nrobots:\n  r1: [0, 0]\n", 3, "list of 3 numbers"),
    ("bad.yaml", "walls: [\n", 2, "invalid YAML"),
]


@pytest.mark.parametrize("name,text,line,message", BAD, ids=[b[3] for b in BAD])
def test_malformed_world_names_file_and_line(tmp_path, name, text, line, message):
    f = tmp_path / name
    f.write_text(text)
    with pytest.raises(ConfigError) as err:
        load_world(f)
    assert err.value.line == line and message in str(err.value)
    assert str(f) in str(err.value)


def test_mrta_sim_exits_2_on_a_malformed_map_naming_file_and_line(tmp_path):
    f = tmp_path / "bad.map"
    f.write_text("2D-Map\nLINES\n0 0 1000\n")
    res = CliRunner().invoke(cli, ["sim", "--world", str(f), "--robot", "r1=0,0,0"])
    assert res.exit_code == 2
    assert f"{f}:3:" in res.output and "needs 4 numbers" in res.output


@pytest.mark.parametrize("args,message", [
    (["--world", "nowhere", "--robot", "r1"], "no such world"),
    (["--world", "patrol", "--robot", "r1=1,2,x"], "must be numbers"),
    (["--world", "patrol", "--robot", "r1=nohome"], "no start named 'nohome'"),
    (["--world", "patrol", "--robot", "r1", "--robot", "r1"], "more than once"),
    (["--world", "patrol", "--robot", "robot1", "--speed", "-1"], "--speed"),
])
def test_mrta_sim_bad_arguments_exit_2(args, message):
    res = CliRunner().invoke(cli, ["sim", *args])
    assert res.exit_code == 2, res.output
    assert message in res.output


def test_robots_take_named_then_free_start_poses():
    w = load_world(PATROL_WORLD)
    poses = place_robots(w, [parse_robot("robot2"), parse_robot("x=robot1"),
                             parse_robot("y"), parse_robot("z=1,2")])
    assert poses["robot2"] == w.starts["robot2"] and poses["x"] == w.starts["robot1"]
    assert poses["y"] == w.starts["robot3"]  # next free start not claimed by name
    assert poses["z"] == Pose(1.0, 2.0, 0.0)


def test_a_map_over_8_mib_exits_2_naming_the_file(tmp_path):
    """A valid map past the bound the YAML files have (yamlfile.MAX_BYTES) is refused unread,
    not parsed into 800,000 walls."""
    f = tmp_path / "huge.map"
    f.write_text("2D-Map\nLINES\n" + "0 0 1000 0\n" * 800_000)
    assert f.stat().st_size > 8 * 1024 * 1024
    with pytest.raises(ConfigError) as err:
        load_world(f)
    assert "larger than 8 MiB" in str(err.value) and str(f) in str(err.value)
    res = CliRunner().invoke(cli, ["sim", "--world", str(f), "--robot", "r1=0,0,0"])
    assert res.exit_code == 2 and str(f) in res.output and "Traceback" not in res.output
