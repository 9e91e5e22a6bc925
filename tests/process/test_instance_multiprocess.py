"""Instances as run input, end to end: `mrta instance generate` writes a 3-robot instance with a
wall, `mrta demo --application delivery --instance FILE` runs it under ALLIANCE and under
MURDOCH with exactly its robots, every task is delivered, no robot touches the wall, the
summary's `instance` section fed back as `--instance` gives the same run, and nothing is
written into the installed packages."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from tests.harness.helpers import CONFIGS

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

DURATION = "45"  # simulated s: this instance's last delivery ends at ≈ 26 s under ALLIANCE
# seed 2: the wall stands between robot1 and t1 (their path is 2.8 × the straight line)
GENERATE = ["instance", "generate", "delivery", "--robots", "3", "--tasks", "3", "--walls", "1",
            "--wall-length", "4", "6", "--capabilities", "", "--seed", "2"]


def run_demo(children, out: Path, *args: str) -> dict:
    return children.demo(out, "--application", "delivery", "--duration", DURATION, *args,
                         quiet=True).summary(200)


def installed_state() -> dict[str, tuple[int, int]]:
    return {str(p): (p.stat().st_size, p.stat().st_mtime_ns)
            for name in ("delivery", "delivery_murdoch")
            for p in (CONFIGS / "applications" / name).rglob("*") if p.is_file()
            and "__pycache__" not in p.parts}


def recorded(out: Path, walls: list) -> tuple[float, set]:
    """The least distance of any robot's centre (simulator ground truth) to an inner wall, and
    the walls the simulator said its world has (its `world` messages)."""
    from mrta_zenoh.codec import decode, type_from_encoding
    from mrta_zenoh.planning.geometry import point_segment_distance
    from mrta_zenoh.recording import read_recording
    least, simulated = math.inf, set()
    for key, enc, _t, payload in read_recording(out / "run.mcap"):
        if key.endswith("/ground_truth"):
            pose = decode(type_from_encoding(enc), payload).pose
            least = min(least, min(point_segment_distance((pose.x, pose.y), w) for w in walls))
        elif key == "world":
            simulated |= {tuple(round(v, 3) for v in (w.x1, w.y1, w.x2, w.y2))
                          for w in decode(type_from_encoding(enc), payload).walls}
    return least, simulated


@pytest.mark.timeout(900)
def test_a_generated_instance_with_a_wall_runs_under_both_architectures_and_round_trips(
        children, tmp_path):
    from mrta_delivery.instance import load_document
    from mrta_zenoh.planning.geometry import ROBOT_RADIUS
    before = installed_state()
    file = tmp_path / "inst.yaml"
    gen = children.mrta(*GENERATE, "-o", str(file), name="generate")
    assert gen.wait(60) == 0, gen.tail(10)
    doc = load_document(file)
    walls = [list(w) for w in doc.world.walls]
    assert len(doc.robots) == 3 and len(walls) == 1

    alliance = run_demo(children, tmp_path / "alliance", "--instance", str(file))
    murdoch = run_demo(children, tmp_path / "murdoch", "--instance", str(file),
                       "--architecture", "murdoch")
    for s, arch, pkg in ((alliance, "alliance", "delivery"),
                         (murdoch, "murdoch", "delivery_murdoch")):
        assert (s["mission"], s["application"], s["architecture"]) == ("delivery", pkg, arch)
        assert sorted(s["who_did_what"]) == ["robot1", "robot2", "robot3"]  # the instance's 3
        assert s["metrics"]["completed"] == s["metrics"]["tasks"] == 3, s["metrics"]
        assert s["instance"]["name"] == "delivery-r3-t3-w1-2"  # a walled instance says so
        assert s["instance"]["world"]["walls"] == walls
        assert "around the walls" in s["instance"]["cost_model"]
        out = tmp_path / arch
        assert (out / "instance" / "delivery" / "worlds" / "delivery.yaml").is_file()
        least, simulated = recorded(out, walls)
        assert tuple(walls[0]) in simulated  # the simulator ran the instance's world
        assert least > ROBOT_RADIUS + 0.05  # and no robot touched its wall
    # the section read back is the same instance (its cost and cost_model ignored)
    again = load_document(tmp_path / "alliance" / "summary.json")
    assert again.body() == doc.body()
    # and run again, it gives the same run: the same seed, the same allocation
    rerun = run_demo(children, tmp_path / "rerun", "--instance",
                     str(tmp_path / "alliance" / "summary.json"))
    assert rerun["instance"] == alliance["instance"]
    assert rerun["allocation"] == alliance["allocation"]
    assert rerun["metrics"] == alliance["metrics"]
    assert installed_state() == before  # nothing written into the installed packages
