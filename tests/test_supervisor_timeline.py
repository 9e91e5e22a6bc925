"""The allocation timeline draws what the robots said they did — the summary's ground truth —
not the supervisor's lagging view: robot3's report ends where the
summary says, one run gives one picture whatever the recorder's timing, the legend lists
tasks in natural order and `offline` only when a robot was."""

from __future__ import annotations

import pytest

from mrta_agent.alliance.messages import InterRobotCommunication, Motivation
from mrta_zenoh import codec
from mrta_zenoh.clock import SimClock
from mrta_zenoh.keys import CLOCK
from mrta_zenoh.messages import Clock, Header
from mrta_zenoh.recording import McapRecorder, SimLogTime
from mrta_zenoh.toolchain.model import ApplicationFile, RobotEntry
from mrta_supervisor.mission import plots
from mrta_supervisor.live.api import resolve_application

NS = 1_000_000_000
TICK = 0.1


def enc(msg):
    return codec.encoding_for(msg.TYPE_NAME), codec.encode(msg)


def record(path, doing: dict, end: float, jitter: float = 0.0, gone: dict | None = None):
    """A simulated-time recording of ALLIANCE robots: `doing` robot → [(task, start, stop)];
    each active robot says so every tick (Motivation) and broadcasts every second (IRC);
    `jitter` delays the broadcasts' log times by up to twice as much, varying (the recorder
    hearing them late, after the next clock); `gone` robot → when its agent token went."""
    gone = gone or {}
    with McapRecorder(path, log_time=SimLogTime(SimClock())) as rec:
        def put(key, msg, t, late=0.0):
            e, payload = enc(msg)
            rec.sample(key, e, payload, int(round((t + late) * NS)))

        for rid in doing:
            rec.liveliness(f"{rid}/alliance/agent", True, 0)
        n = int(round(end / TICK))
        for i in range(n + 1):
            t = round(i * TICK, 6)
            put(CLOCK, Clock(t, "run-x0"), t)
            for rid, spans in doing.items():
                if rid in gone and t > gone[rid]:
                    continue
                tasks = {task for task, _, _ in spans}
                for task in sorted(tasks):
                    active = any(task == tk and a <= t < b for tk, a, b in spans)
                    put(f"{rid}/alliance/motivation/{task}",
                        Motivation(Header(rid, t, i), task, 0.1, False, False, False, True,
                                   1.0 if active else 0.0, 1.0, active), t)
                    if active and i % 10 == 0:
                        put(f"{rid}/alliance/inter_robot_communication",
                            InterRobotCommunication(Header(rid, t, i), task, 60.0), t,
                            jitter * (i // 10 % 3))
        for rid, at in gone.items():
            rec.liveliness(f"{rid}/alliance/agent", False, int(round(at * NS)))


@pytest.fixture
def panels(monkeypatch):
    """The panels plot_timeline draws (and the figure's legend labels), captured."""
    seen: dict = {}
    draw = plots.draw_timeline

    def capture(output, app, panels_, span, xlabel, **kw):
        seen["panels"] = panels_
        return draw(output, app, panels_, span, xlabel, **kw)

    save = plots.save_figure

    def save_capture(fig, output):
        seen["legend"] = [t.get_text() for t in fig.legends[0].get_texts()]
        return save(fig, output)

    monkeypatch.setattr(plots, "draw_timeline", capture)
    monkeypatch.setattr(plots, "save_figure", save_capture)
    return seen


@pytest.mark.slow
def test_the_timeline_ends_robot3s_report_where_the_robots_said(tmp_path, panels):
    app, arch = resolve_application("patrol")
    rec = tmp_path / "run.mcap"
    record(rec, {"robot1": [("wander", 0.4, 20.0)], "robot3": [("report", 0.6, 12.3)]}, 20.0)
    plots.plot_timeline(rec, app, arch, tmp_path / "t.png", view="both")
    robots, supervisor = panels["panels"]
    (task, a, b), = robots.intervals["robot3"]
    assert task == "report" and a == pytest.approx(0.6) and b == pytest.approx(12.3)
    # the supervisor's view, drawn beside and labelled, lags by its monitor's 2.5 s timeout
    (_, _, sb), = supervisor.intervals["robot3"]
    assert sb > 12.3 + 1.0
    assert "supervisor" in supervisor.title and "robots" in robots.title
    assert panels["legend"] == ["border_protection", "report", "wander"]  # nobody offline


@pytest.mark.slow
def test_one_run_gives_one_picture_whatever_the_recorders_timing(tmp_path):
    app, arch = resolve_application("patrol")
    doing = {"robot1": [("wander", 0.4, 30.0)],
             "robot2": [("border_protection", 0.4, 1.0), ("border_protection", 2.3, 30.0)]}
    for name, jitter in (("a", 0.0), ("b", 0.15)):
        record(tmp_path / f"{name}.mcap", doing, 30.0, jitter)
        plots.plot_timeline(tmp_path / f"{name}.mcap", app, arch, tmp_path / f"{name}.png")
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()


def test_the_legend_lists_tasks_in_natural_order_and_offline_only_when_a_robot_was(
        tmp_path, panels):
    _, arch = resolve_application("patrol")
    tasks = ["t1", "t2", "t4", "t3", "t10"]  # the application's (first-seen) order
    app = ApplicationFile("alliance", "Delivery", [RobotEntry("robot1", tasks),
                                                   RobotEntry("robot2", tasks)])
    rec = tmp_path / "d.mcap"
    record(rec, {"robot1": [("t4", 0.5, 5.0)], "robot2": [("t3", 0.5, 9.0)]}, 10.0,
           gone={"robot2": 9.0})
    plots.plot_timeline(rec, app, arch, tmp_path / "d.png")
    assert panels["legend"] == ["t1", "t2", "t3", "t4", "t10", "offline"]
    (offline,) = panels["panels"][0].offline["robot2"]
    assert offline == pytest.approx((9.0, 10.0))


def test_an_architecture_without_a_contract_asks_for_the_supervisors_view(tmp_path):
    from mrta_zenoh.errors import ConfigError

    app, arch = resolve_application("patrol")
    app = ApplicationFile("no_such_arch", "X", app.robots)
    rec = tmp_path / "r.mcap"
    record(rec, {"robot1": [("wander", 0.4, 3.0)]}, 3.0)
    with pytest.raises(ConfigError, match="--view supervisor"):
        plots.plot_timeline(rec, app, arch, tmp_path / "x.png")
    plots.plot_timeline(rec, app, arch, tmp_path / "x.png", view="supervisor")
    assert (tmp_path / "x.png").stat().st_size > 1000
