"""`mrta supervise`, `mrta record` and `mrta plot` against fake robots in their own processes."""

import json
import signal
import time

import pytest
from mcap.reader import make_reader

from mrta_zenoh.keys import LIVELINESS_PREFIX
from tests.harness.helpers import png_size

pytestmark = pytest.mark.multiprocess


def snapshots(sup, pred, timeout):
    return sup.wait_json(pred, timeout)


def robots_of(snap):
    return {r["id"]: (r["state"], r["task"]) for r in snap["robots"]}


def test_supervise_json_busy_idle_offline_then_sigkill_is_offline_by_its_token(children, tokens,
                                                                              tmp_path):
    rec_file = tmp_path / "run.mcap"
    recorder = children.mrta("record", "-o", str(rec_file), name="record")
    tokens.wait("@mrta/recorder/*", 20, recorder)
    sup = children.mrta("supervise", "patrol", "--json", "--rate", "20", name="supervise")
    r1 = children.python("fake_robot.py", "robot1", "wander", name="robot1")
    r2 = children.python("fake_robot.py", "robot2", name="robot2")
    tokens.wait_all(["robot1/alliance/agent", "robot2/alliance/agent"], 20, r1, r2)
    snap = snapshots(sup, lambda s: robots_of(s).get("robot1") == ("busy", "wander")
                     and robots_of(s).get("robot2") == ("idle", None), 20)
    assert robots_of(snap)["robot3"] == ("offline", None)
    tasks = {t["id"]: t for t in snap["tasks"]}
    assert tasks["wander"]["state"] == "allocated" and tasks["wander"]["robots"] == ["robot1"]
    # the fake robots' wrong-type and malformed samples are counted, not crashing anything
    snap = snapshots(sup, lambda s: s["counts"]["wrong_type"] >= 1, 10)
    assert robots_of(snap)["robot1"] == ("busy", "wander")
    # a stretch of motivation to plot, and more than 20 samples to record: counted by the
    # supervisor, which hears what the recorder hears (a sleep made this depend on the speed)
    snap = snapshots(sup, lambda s: s["counts"]["samples"] >= 25, 20)
    # offline because of the kill, not before it, and by its liveliness token (the only way a
    # robot that had one goes offline, with communication_lost): by the order of events, not
    # by a latency in wall seconds — the 30 s is a hang guard, not a speed asserted
    assert robots_of(snap)["robot1"] == ("busy", "wander")
    lost = [(a["kind"], a["subject"]) for a in snap["alarms"]]
    assert ("communication_lost", "robot1") not in lost
    t_kill = time.time()
    r1.signal(signal.SIGKILL)
    snap = snapshots(sup, lambda s: robots_of(s).get("robot1", ("",))[0] == "offline", 30)
    print(f"SIGKILL → offline in the supervisor's snapshot: {snap['time'] - t_kill:.3f} s")
    assert snap["time"] >= t_kill
    assert {"kind": "communication_lost", "subject": "robot1"} in [
        {k: a[k] for k in ("kind", "subject")} for a in snap["alarms"]]
    time.sleep(0.5)
    recorder.signal(signal.SIGINT)
    assert recorder.wait(10) == 130  # Ctrl-C: the shell's 128 + SIGINT, after a clean finish
    sup.signal(signal.SIGTERM)
    assert sup.wait(10) == 0

    with open(rec_file, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic: c for c in summary.channels.values()}
        assert "robot1/alliance/inter_robot_communication" in topics
        assert topics["robot1/alliance/motivation/wander"].metadata["type"] == "alliance_msgs/Motivation"
        assert any(t.startswith(f"{LIVELINESS_PREFIX}robot1/") for t in topics)
        assert summary.statistics.message_count > 20

    fig = tmp_path / "motivation.png"
    plot = children.mrta("plot", "motivation", str(rec_file), "--robot", "robot1", "--task",
                         "wander", "-o", str(fig), name="plot-m")
    assert plot.wait(60) == 0, plot.stderr
    assert png_size(fig) == (1000, 1200)
    gantt = tmp_path / "timeline.png"
    plot = children.mrta("plot", "timeline", str(rec_file), "--app", "patrol", "-o", str(gantt),
                         name="plot-t")
    assert plot.wait(60) == 0, plot.stderr
    w, h = png_size(gantt)
    assert (w, h) == (1200, 310) and gantt.stat().st_size > 10_000
    bad = children.mrta("plot", "motivation", str(rec_file), "--robot", "robot1", "--task",
                        "report", "-o", str(tmp_path / "x.png"), name="plot-bad")
    assert bad.wait(60) == 2
    assert any("tasks recorded for robot1: wander" in line for line in bad.stderr)


@pytest.mark.slow
def test_supervise_once_prints_one_snapshot_and_exits(children, tokens):
    r2 = children.python("fake_robot.py", "robot2", "report", name="robot2")
    tokens.wait("robot2/alliance/agent", 20, r2)
    started = time.time()
    sup = children.mrta("supervise", "patrol", "--once", "--json", name="once")
    assert sup.wait(30) == 0
    lines = [json.loads(x) for x in sup.stdout if x.startswith("{")]
    assert len(lines) == 1
    assert robots_of(lines[0])["robot2"] == ("busy", "report")
    assert started <= lines[0]["time"] <= time.time()  # a snapshot of now, in wall time
