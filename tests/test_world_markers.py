"""A world's named markers: points a world file names, or an instance's tasks (`mrta sim
--markers INSTANCE`: delivery's), marked on the simulator's snapshot (world.png) — the simulator
knows no application by them."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from mrta_simulator import snapshot
from mrta_simulator.api import with_instance_markers
from mrta_simulator.engine import Simulation
from mrta_simulator.world import Pose, load_world
from mrta_zenoh.errors import ConfigError

DELIVERY = Path(__file__).resolve().parents[1] / "configs" / "applications" / "delivery"


def world_file(tmp_path, extra: str) -> Path:
    f = tmp_path / "w.yaml"
    f.write_text("walls:\n  - polygon: [[-5, -5], [5, -5], [5, 5], [-5, 5]]\n" + extra)
    return f


def test_a_world_files_markers_are_marked_on_the_snapshot(tmp_path, monkeypatch):
    world = load_world(world_file(tmp_path, 'markers:\n  t1: [1.5, -2]\n  "7": [0, 3]\n'))
    assert world.markers == {"t1": (1.5, -2.0), "7": (0.0, 3.0)}
    drawn = {}

    def capture(fig, path):
        ax = fig.axes[0]
        drawn["texts"] = {t.get_text(): t.xy for t in ax.texts}
        drawn["points"] = {(float(x), float(y)) for line in ax.lines
                           if line.get_marker() == "x"
                           for x, y in zip(line.get_xdata(), line.get_ydata())}
        # above the robots' discs: a robot standing on its task must not hide the mark
        drawn["above"] = min(line.get_zorder() for line in ax.lines if line.get_marker() == "x") \
            > max(p.get_zorder() for p in ax.patches)

    monkeypatch.setattr(snapshot, "save_figure", capture)
    sim = Simulation(world, {"robot1": Pose(1.5, -2.0, 0.0)})  # on t1
    snapshot.save_snapshot(sim, tmp_path / "world.png")
    assert drawn["points"] == {(1.5, -2.0), (0.0, 3.0)} and drawn["above"]
    assert drawn["texts"]["t1"] == (1.5, -2.0) and drawn["texts"]["7"] == (0.0, 3.0)


@pytest.mark.parametrize("extra,line,message", [
    ("markers: [1, 2]\n", 3, "maps a name to [x, y]"),
    ("markers:\n  t1: [1]\n", 4, "2 numbers"),
    ("markers:\n  t1: [1, .nan]\n", 4, "finite"),
    ("marker:\n  t1: [1, 2]\n", 3, "did you mean 'markers'"),
])
def test_a_bad_marker_names_file_and_line(tmp_path, extra, line, message):
    f = world_file(tmp_path, extra)
    with pytest.raises(ConfigError) as err:
        load_world(f)
    assert err.value.line == line and message in str(err.value) and str(f) in str(err.value)


def test_deliverys_simulator_marks_every_task_of_its_packages_instance():
    """The delivery launch files give the simulator their package's instance (`--markers`):
    each task is marked where the instance places it, and the world file places none."""
    instance = DELIVERY / "config" / "instance.yaml"
    tasks = yaml.safe_load(instance.read_text())["tasks"]
    plain = load_world(DELIVERY / "worlds" / "delivery.yaml")
    assert plain.markers == {}
    marked = with_instance_markers(plain, instance)
    assert marked.markers == {tid: tuple(map(float, t["position"])) for tid, t in tasks.items()}
    launch = (DELIVERY / "launch" / "delivery_sim.launch").read_text()
    assert "--markers $(find delivery)/config/instance.yaml" in launch
