"""Fault models beyond crash-stop, end to end: the patrol demo in lockstep with a robot that
stalls (alive, still broadcasting or renewing its lease, no progress).

ALLIANCE: patrol's tasks announce φ (task_expected_duration) = 600 s, longer than a test run,
so the run uses a package copy (as `mrta experiment`'s overrides do) with wander's φ at 30 s:
robot3, idle once its report is done, grows impatient with the stalled robot1 once φ has run out
and takes wander over. MURDOCH: the stalled robot keeps renewing its lease, so its task is
re-auctioned only once its auctioneer revokes the contract past the task's `progress_timeout`
(docs/murdoch.md, "Progress monitoring") — 600 s for patrol's wander and border protection,
so it keeps its task through this 60 s run (tests/test_murdoch_progress.py checks the
revocation)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

WANDER_PHI = 30.0
STALL_AT = 15.0


def run_demo(children, out: Path, *args: str, env: dict | None = None) -> dict:
    children.env.update(env or {})  # this test's children only (the fixture is per test)
    return children.demo(out, "--application", "patrol", *args, quiet=True).summary(240)


def assert_stood_still_from(out: Path, robot: str, at: float) -> None:
    """The robot's recorded odometry: it moved before `at`, and not one millimetre after
    (its layers stopped: the stall, not a crash — its agent is still talking)."""
    from mrta_zenoh import keys
    from mrta_zenoh.codec import decode, type_from_encoding
    from mrta_zenoh.recording import read_recording
    poses = []
    for key, enc, _t, payload in read_recording(out / "run.mcap"):
        if key == keys.odom(robot):
            m = decode(type_from_encoding(enc), payload)
            poses.append((m.header.stamp, m.pose.x, m.pose.y))
    before = [(x, y) for t, x, y in poses if t <= at]
    after = [(x, y) for t, x, y in poses if t >= at + 1.0]
    assert before and after and len(set(before)) > 10  # it was moving
    x0, y0 = after[0]
    assert all(abs(x - x0) < 1e-3 and abs(y - y0) < 1e-3 for x, y in after)


@pytest.mark.timeout(300)
def test_alliance_takes_over_the_task_of_a_stalled_robot(children, tmp_path):
    from mrta_supervisor.experiment.api import package_copy
    from mrta_zenoh.toolchain.registry import Registry
    package_copy(Registry().find("patrol").path, tmp_path / "pkg",
                 (("robot*.behaviour_sets.behaviour_set0.task_expected_duration", WANDER_PHI),))
    s = run_demo(children, tmp_path / "a", "--duration", "60",
                 "--fail", f"stall:robot1@{STALL_AT:g}",
                 env={"MRTA_PACKAGE_PATH": str(tmp_path / "pkg")})
    f = s["failure"]
    print(json.dumps(f))
    assert (f["robot"], f["killed_at"], f["task"]) == ("robot1", STALL_AT, "wander")
    assert f["fault"] == "stall"  # summary.json says which fault it was
    assert f["taken_over_by"] in ("robot2", "robot3")
    # φ runs from robot1's first broadcast (≈ 0.4 s), then ⌈θ/δ_fast⌉ ticks of impatience
    assert WANDER_PHI - STALL_AT < f["takeover_seconds"] < WANDER_PHI - STALL_AT + 5.0
    assert "bound_seconds" not in f  # the silence bound says nothing about a stall
    # the stalled robot still claims wander to the end: alive, broadcasting, stuck
    assert s["who_did_what"]["robot1"][-1]["task"] == "wander"
    assert s["who_did_what"]["robot1"][-1]["to"] == pytest.approx(60.0, abs=1.0)
    assert_stood_still_from(tmp_path / "a", "robot1", STALL_AT)


@pytest.mark.timeout(300)
def test_murdoch_keeps_a_stalled_robots_lease_alive(children, tmp_path):
    s = run_demo(children, tmp_path / "m", "--architecture", "murdoch", "--duration", "60",
                 "--fail", f"stall:robot1@{STALL_AT:g}")
    f = s["failure"]
    print(json.dumps(f))
    assert (f["robot"], f["killed_at"]) == ("robot1", STALL_AT) and f["task"]
    assert "taken_over_by" not in f  # renewed, and revoked only past its 600 s progress_timeout
    spans = [x for r, xs in s["who_did_what"].items() for x in xs if x["task"] == f["task"]]
    assert {x["task"] for x in s["who_did_what"]["robot1"]} == {f["task"]}
    assert len(spans) == 1 and spans[0]["to"] == pytest.approx(60.0, abs=1.0)
    assert_stood_still_from(tmp_path / "m", "robot1", STALL_AT)


@pytest.mark.timeout(300)
def test_a_partition_with_loss_and_latency_is_taken_over_and_replays_exactly(children, tmp_path):
    """robot1 cut off for 8 s, every coordination message 20 % lost and 0.3 ± 0.2 s late:
    ALLIANCE hears silence, robot3 (idle) takes wander within the bound, robot1 rejoins; the
    same seed loses and delays the same messages, so the run replays exactly."""
    spec = "partition:robot1@15+8,loss:0.2,latency:0.3±0.2"
    runs = [run_demo(children, tmp_path / f"p{i}", "--duration", "45", "--fail", spec)
            for i in (1, 2)]
    f = runs[0]["failure"]
    print(json.dumps(f))
    assert (f["robot"], f["task"], f["taken_over_by"]) == ("robot1", "wander", "robot3")
    assert 0 < f["takeover_seconds"] <= f["bound_seconds"]
    # cut off, it went on wandering: its broadcasts are recorded (nobody heard them), so its
    # stretch covers the cut — what it did, not what its teammates heard
    assert any(x["task"] == "wander" and x["from"] <= 15.0 and x["to"] >= 23.0
               for x in runs[0]["who_did_what"]["robot1"])
    assert runs[0]["fault_effects"]["cut_off"] > 0 and runs[0]["fault_effects"]["lost"] > 0
    # the same seed, the same run (within one agent tick: docs/delivery.md, Tests)
    a, b = (r["who_did_what"] for r in runs)
    assert {k: [x["task"] for x in v] for k, v in a.items()} == \
        {k: [x["task"] for x in v] for k, v in b.items()}
    for k in a:
        for x, y in zip(a[k], b[k]):
            assert abs(x["from"] - y["from"]) <= 0.11 and abs(x["to"] - y["to"]) <= 0.11
