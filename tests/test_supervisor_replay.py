"""A replay's clock, followed as a simulator's is: `mrta replay --clock`
announces each recorded run under an id naming the replay's own pace and holds its clock-source
token while it plays it, so a follower's creep bound trusts it at that pace, and sees the run
end when the replay is over."""

from __future__ import annotations

import json
import threading

import pytest

from mrta_zenoh import codec
from mrta_zenoh.clock import RATE_MARGIN, SimClock, run_speed
from mrta_zenoh.keys import CLOCK, CLOCK_SOURCE_TOKEN
from mrta_zenoh.messages import Clock
from mrta_zenoh.recording import McapRecorder, SimLogTime, read_recording
from mrta_zenoh.tools import replay as replay_mod
from mrta_zenoh.tools.replay import MAX_LAG, announce_runs, plan_replay

NS = 1_000_000_000
CLOCK_ENC = codec.encoding_for(Clock.TYPE_NAME)


def recording(path, run: str, seconds: float, speed: float, simulated: bool, step=0.1,
              robot: str | None = None):
    """A recording of `run`'s clock for `seconds` simulated, every `step`: in simulated time,
    or in the wall time of a run at `speed`; with `robot`, its agent's token from the start
    to after the last clock (its process stopping as the run ends)."""
    log_time = SimLogTime(SimClock()) if simulated else None
    with McapRecorder(path, log_time=log_time) as rec:
        if robot is not None:
            rec.liveliness(f"{robot}/alliance/agent", True, 0)
        n = int(round(seconds / step))
        for i in range(n + 1):
            stamp = round(i * step, 6)
            t = stamp if simulated else stamp / speed
            rec.sample(CLOCK, CLOCK_ENC, codec.encode(Clock(stamp, run)), int(t * NS))
        if robot is not None:
            rec.liveliness(f"{robot}/alliance/agent", False, int(t * NS) + 1)
    return read_recording(path)


def follow(plan, speed: float) -> SimClock:
    """A SimClock fed the plan's clock samples and tokens at the wall times the replay sends
    them (its pace: `at / speed`), as a follower on the bus would get them."""
    wall = [0.0]
    clock = SimClock(wall=lambda: wall[0])
    for step in plan.steps:
        wall[0] = step.at / speed
        if step.alive is not None:
            assert step.key.startswith(CLOCK_SOURCE_TOKEN + "/")
            clock.on_source(step.key[len(CLOCK_SOURCE_TOKEN) + 1:], step.alive)
        elif step.key == CLOCK:
            msg = codec.decode(Clock.TYPE_NAME, step.payload)
            clock.on_clock(msg.stamp, msg.source)
    return clock


@pytest.mark.parametrize("simulated", [False, True])
def test_a_replay_at_four_times_is_followed_to_its_last_stamp(tmp_path, simulated):
    """A 64 s run recorded at speed 2, replayed at --speed 4: the follower's time reached
    15.9 s of 64 (39.3 s at --speed 2) when the replay kept the recorded run's id."""
    records = recording(tmp_path / "run.mcap", "3f2a9c1b7d4e-x2", 64.0, 2.0, simulated)
    plan = announce_runs(plan_replay(records, clock=True), 4.0, simulated)
    clock = follow(plan, 4.0)
    assert clock.now() == pytest.approx(64.0) and clock.rejected == 0
    pace = 4.0 if simulated else 8.0  # simulated seconds per wall second of the replay
    assert run_speed(clock.source) == pace
    assert clock.ended()  # the replay's token went with its last sample
    # what the replay did before: the recorded id, whose speed bounds the pace at 2 × 1.5
    before = follow(plan_replay(records, clock=True), 4.0)
    assert before.now() < 64.0 and before.rejected > 0
    assert 2.0 * RATE_MARGIN < pace


def test_each_recorded_run_gets_its_own_id_and_token(tmp_path):
    """A recording with a restarted simulator replays as two runs, each announced once."""
    path = tmp_path / "two.mcap"
    with McapRecorder(path) as rec:
        for i, (run, stamp) in enumerate([("aaaa-x1", 1.0), ("aaaa-x1", 2.0),
                                          ("bbbb-x0", 0.5), ("bbbb-x0", 0.6)]):
            rec.sample(CLOCK, CLOCK_ENC, codec.encode(Clock(stamp, run)), (i + 1) * NS)
        rec.sample("robot1/odom", "application/octet-stream", b"x", 9 * NS)
    plan = announce_runs(plan_replay(read_recording(path), clock=True), 2.0, False)
    kinds = [("end " if s.key.endswith("/ended") else "")
             + (("up" if s.alive else "down") if s.alive is not None else s.key)
             for s in plan.steps]
    # each run's end announced before its token goes (followers see an end, not a death)
    assert kinds == ["up", CLOCK, CLOCK, "end up", "down", "end down",
                     "up", CLOCK, CLOCK, "end up", "down", "end down", "robot1/odom"]
    ids = [s.key.rsplit("/", 1)[1] for s in plan.steps
           if s.alive and not s.key.endswith("/ended")]
    assert len(set(ids)) == 2 and [run_speed(i) for i in ids] == [2.0, 0.0]
    stamps = [codec.decode(Clock.TYPE_NAME, s.payload) for s in plan.steps if s.key == CLOCK]
    assert [(c.stamp, c.source) for c in stamps] == [(1.0, ids[0]), (2.0, ids[0]),
                                                     (0.5, ids[1]), (0.6, ids[1])]


def test_a_replay_that_falls_behind_slips_instead_of_bursting(monkeypatch):
    """A stall of 5 wall seconds in a replay at speed 4: afterwards the replay keeps the
    recording's pace (at most MAX_LAG behind), never publishing faster to catch up."""
    plan = replay_mod.Plan(steps=[replay_mod.Step(i * 0.1, "k", "e", b"") for i in range(400)])
    now = [0.0]
    sent: list[tuple[float, float]] = []

    class Bus:
        def publish_raw(self, key, enc, payload):
            sent.append((plan.steps[len(sent)].at, now[0]))
            if len(sent) == 100:
                now[0] += 5.0  # the machine stalls here

    def wait(stop, seconds):
        now[0] += seconds
        return False

    monkeypatch.setattr(replay_mod.time, "monotonic", lambda: now[0])
    monkeypatch.setattr(replay_mod, "wait_for_stop", wait)
    assert replay_mod.execute(plan, Bus(), 4.0, threading.Event()) == 400
    a0, w0 = sent[100]  # the first sample after the stall
    for a1, w1 in sent[101:]:
        assert (a1 - a0) / 4.0 <= (w1 - w0) + MAX_LAG / 4.0 + 1e-9


def test_a_runs_end_is_given_time_to_be_seen_before_its_processes_exit(monkeypatch, tmp_path):
    """`mrta supervise --sim-time` after a replay of the demo showed robot1 offline with
    `communication_lost` (issue 51, the newcomer's list): its agent's token, recorded going as
    the run's processes stopped, went out the same instant as the run's end, and the follower
    sometimes handled it first. The replay settles (END_SETTLE wall seconds) after announcing a
    run's end, as a live run's simulator ends before its processes are stopped."""
    records = recording(tmp_path / "r.mcap", "aaaa-x1", 1.0, 1.0, True, robot="robot1")
    plan = announce_runs(plan_replay(records, clock=True), 4.0, True)
    said: list[str] = []

    class Bus:
        def publish_raw(self, key, enc, payload):
            said.append(key)

        def declare_token(self, key):
            said.append(f"up {key}")
            return type("Token", (), {"close": lambda _: said.append(f"down {key}")})()

    def wait(stop, seconds):
        said.append(f"wait {seconds}")
        return False

    monkeypatch.setattr(replay_mod, "wait_for_stop", wait)
    replay_mod.execute(plan, Bus(), 0.0, threading.Event())
    end = said.index(f"wait {replay_mod.END_SETTLE}")
    assert said[end - 1].startswith("down " + CLOCK_SOURCE_TOKEN) and said[end - 1].endswith(
        "/ended")  # the end announced whole, then the pause
    assert said[end + 1:] == ["down robot1/alliance/agent"] and replay_mod.END_SETTLE >= 0.5


@pytest.mark.slow
@pytest.mark.multiprocess
def test_supervise_follows_a_fast_replay_to_its_end_and_stops_there(children, tmp_path):
    """`mrta replay --speed 4 --clock` of a recording made at speed 2 beside `mrta supervise
    --sim-time --duration N`: the supervisor's time reaches the recording's end, robots never
    turn `unknown` nor raise `communication_lost` as the run ends, and the supervisor exits
    once the replay is over although N never passed."""
    rec = tmp_path / "run.mcap"
    recording(rec, "3f2a9c1b7d4e-x2", 40.0, 2.0, simulated=False, robot="robot1")
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", "--rate", "10",
                        "--duration", "1000", name="supervise")
    replay = children.mrta("replay", str(rec), "--speed", "4", "--clock", name="replay")
    assert replay.wait(120) == 0, replay.stderr
    assert sup.wait(60) == 0, sup.stderr
    snaps = [json.loads(x) for x in sup.stdout if x.startswith("{")]
    assert snaps and snaps[-1]["run_ended"] is True
    assert snaps[-1]["time"] == pytest.approx(40.0, abs=0.5)
    # robot1 was up all along: never `unknown`, and no alarm when its token went at the end
    assert all(s["robots"][0]["state"] == "idle" for s in snaps if s["time"] > 1.0
               and not s["run_ended"])
    kinds = {a["kind"] for s in snaps for a in s["alarms"]}
    assert not kinds & {"communication_lost", "clock_stopped"}, kinds  # (nobody did a task)
