"""What a newcomer asked of the world picture and the timeline (issue 51, the newcomer's list:
"task labels under robot discs, no legend in world.png, colours repeating after 10 robots or
tasks, crashed robots drawn alive, titles without the architecture"; "timeline bars are
clipped at the headline"): each checked on the figure as drawn, before it is written."""

from __future__ import annotations

from pathlib import Path

import pytest
from matplotlib.colors import to_hex

from mrta_simulator import snapshot
from mrta_simulator.engine import Simulation
from mrta_simulator.world import Pose, load_world
from mrta_supervisor.mission import plots
from mrta_zenoh.palette import TAB10, distinct_colors
from mrta_zenoh.toolchain.model import ApplicationFile, RobotEntry


@pytest.mark.parametrize("n", [1, 10, 11, 20, 40, 100])
def test_every_colour_is_its_own(n):
    colors = distinct_colors(n)
    assert len(colors) == n and len(set(colors)) == n
    if n <= 10:  # the shipped missions' pictures keep their colours
        assert colors == list(TAB10[:n])


def captured(monkeypatch, module) -> dict:
    seen: dict = {}

    def capture(fig, path):
        seen["fig"] = fig
        seen["texts"] = [t.get_text() for t in fig.axes[0].texts]
        legend = fig.axes[0].get_legend() or (fig.legends[0] if fig.legends else None)
        seen["legend"] = [t.get_text() for t in legend.get_texts()]
        seen["title"] = fig.axes[0].get_title() or fig._suptitle.get_text()
        seen["suptitle"] = fig._suptitle.get_text() if fig._suptitle else ""
        seen["patches"] = list(fig.axes[0].patches)
        seen["xlim"] = fig.axes[0].get_xlim()
        seen["lines"] = list(fig.axes[0].lines)
        if fig.legends:  # the timeline's legend, below the axes: clear of the axis' label
            renderer = fig.canvas.get_renderer()  # the axes with its ticks and label
            seen["legend_clear"] = fig.axes[-1].get_tightbbox(renderer).y0 > \
                fig.legends[0].get_window_extent(renderer).y1
        Path(path).write_bytes(b"png")
        return Path(path)

    monkeypatch.setattr(module, "save_figure", capture)
    return seen


def test_the_world_picture_tells_twelve_robots_apart_names_the_architecture_and_the_gone(
        tmp_path, monkeypatch):
    f = tmp_path / "w.yaml"
    f.write_text("walls:\n  - polygon: [[-8, -8], [8, -8], [8, 8], [-8, 8]]\n"
                 "markers:\n  t1: [0, 0]\n  t2: [3, 3]\n")
    robots = {f"robot{i}": Pose(-6.0 + i, -5.0 + (i % 3), 0.0) for i in range(1, 13)}
    robots["robot1"] = Pose(0.0, 0.0, 0.0)  # standing on t1
    sim = Simulation(load_world(f), robots)
    seen = captured(monkeypatch, snapshot)
    snapshot.save_snapshot(sim, tmp_path / "world.png", label="CBBA", gone={"robot3"})
    assert "under CBBA" in seen["title"] and "t = 0.0 s" in seen["title"]
    legend = seen["legend"]
    assert [x for x in legend if x.startswith("robot")] == list(robots)
    assert "task (marker)" in legend and "sonar beams" in legend and snapshot.GONE in legend
    discs = seen["patches"]
    assert len(discs) == 12
    alive = [d for d in discs if not d.get_hatch()]
    assert len({to_hex(d.get_facecolor()) for d in alive}) == 11  # no colour twice
    (hollow,) = [d for d in discs if d.get_hatch()]
    assert to_hex(hollow.get_facecolor()) == "#ffffff"
    assert "robot3 (no process)" in seen["texts"] and "robot1" in seen["texts"]
    # every label above every disc, and boxed: a robot on its task hides neither name
    texts = seen["fig"].axes[0].texts
    assert min(t.get_zorder() for t in texts) > max(d.get_zorder() for d in discs)
    assert all(t.get_bbox_patch() is not None for t in texts)
    # `mrta sim` alone knows no architecture, and a run where every process lived has no
    # "gone" entry
    snapshot.save_snapshot(sim, tmp_path / "world.png")
    assert snapshot.GONE not in seen["legend"] and "under" not in seen["title"]


def test_the_timeline_gives_twenty_tasks_twenty_colours_names_the_architecture_and_the_end(
        tmp_path, monkeypatch):
    tasks = [f"t{i}" for i in range(1, 21)]
    app = ApplicationFile("cbba", "Delivery (CBBA)", [RobotEntry("robot1", tasks),
                                                     RobotEntry("robot2", tasks)])
    intervals = {"robot1": [(t, 2.0 * i, 2.0 * i + 1.5) for i, t in enumerate(tasks[:10])],
                 "robot2": [(t, 2.0 * i, 2.0 * i + 1.5) for i, t in enumerate(tasks[10:])]}
    seen = captured(monkeypatch, plots)
    plots.draw_timeline(tmp_path / "t.png", app, [plots.Panel("robots", intervals)],
                        (0.0, 19.5), "simulated time (s)", ended_at=19.5)
    # named once, although the application's name has it already
    assert seen["suptitle"] == "Delivery (CBBA): which robot did which task when"
    assert seen["legend"][:20] == tasks
    assert seen["legend"][20] == f"{plots.WORK_OVER} (19.5 s)"
    bars = seen["fig"].axes[0].collections
    assert len({to_hex(b.get_facecolor()[0]) for b in bars}) == 20
    # the end is marked, and the axis goes a little past it: the bars stop there on purpose
    assert any(list(line.get_xdata()) == [19.5, 19.5] for line in seen["lines"])
    assert seen["xlim"][1] > 19.5
    assert seen["legend_clear"]  # three rows of legend covered it
    plain = ApplicationFile("alliance", "Patrol", [RobotEntry("robot1", ["wander"])])
    plots.draw_timeline(tmp_path / "t.png", plain,
                        [plots.Panel("robots", {"robot1": [("wander", 0.0, 5.0)]})],
                        (0.0, 5.0), "simulated time (s)")
    assert seen["suptitle"] == "Patrol under ALLIANCE: which robot did which task when"
    assert seen["legend"] == ["wander"] and seen["xlim"] == (0.0, 5.0)
