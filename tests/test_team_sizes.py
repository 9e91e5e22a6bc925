"""Teams of many robots (issue 39 point 5): what a robot's start-up costs per task, and a
generated N-robot delivery run in lockstep to its end."""

from __future__ import annotations

import importlib.metadata
import json

import pytest

from mrta_agent.runtime import plugins
from mrta_zenoh import installed


def test_a_robot_reads_the_installed_entry_points_once_whatever_its_tasks(monkeypatch):
    """A delivery robot loads one evaluator per task: reading every distribution's entry points
    for each (≈ 0.1 s) made start-up grow with the tasks; they are read once per import path
    (mrta_zenoh.installed)."""
    calls = []
    read = importlib.metadata.entry_points

    def counting():
        calls.append(1)
        return read()

    monkeypatch.setattr(importlib.metadata, "entry_points", counting)
    installed.forget()
    try:
        loaded = {plugins.load_plugin("evaluator", "delivery/task_open") for _ in range(50)}
        assert len(loaded) == 1 and len(calls) == 1
        monkeypatch.syspath_prepend("/nonexistent-for-this-test")  # another import path
        plugins.load_plugin("evaluator", "delivery/task_open")
        assert len(calls) == 2
    finally:
        installed.forget()


N = 10  # robots and tasks. At 20 the recorder falls behind on a loaded machine (benchmarks/README.md)


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_generated_n_robot_delivery_run_completes_in_lockstep(children, tmp_path):
    """`mrta demo --instance` with a generated 10-robot, 10-task instance at `--speed 0`: every
    robot of the instance runs (its own agent, in the summary), the mission ends with an exact
    lockstep record and a complete recording, and tasks are assigned."""
    from mrta_delivery.instance import load_document

    file = tmp_path / "team.yaml"
    gen = children.mrta("instance", "generate", "delivery", "--robots", str(N), "--tasks",
                        str(N), "--room", "17", "11.3", "--seed", "1", "-o", str(file),
                        name="generate")
    assert gen.wait(120) == 0, gen.tail(10)
    robots = sorted(load_document(file).robots)
    assert len(robots) == N

    out = tmp_path / "run"
    s = children.demo(out, "--application", "delivery", "--instance", file, "--duration", "10",
                      "--no-plots", "--fail", "none", quiet=True).summary(800)
    assert s["lockstep"] is True and s["lockstep_exact"] is True, s["run_status"]
    assert s["run_status"] == "complete" and s["lockstep_given_up"] == 0
    assert s["recorded_until"] >= 10.0
    assert sorted(s["robots"]) == robots and sorted(s["who_did_what"]) == robots
    assert s["metrics"]["tasks"] == N and s["metrics"]["assigned"] > 0


@pytest.mark.multiprocess
def test_a_sample_over_3_kb_maps_no_shared_memory_pool(tmp_path):
    """Zenoh's shared-memory transport put a 16 MB pool, all of it resident, into every process
    that sent a sample over 3 kB: 16 MB more per agent from 20 robots up. Our sessions send
    such samples over the network like any other."""
    import time

    import zenoh

    from mrta_zenoh.bus.options import base_config, private_rendezvous

    endpoint = private_rendezvous()
    first, second = base_config("peer"), base_config("peer")
    first["listen"] = {"endpoints": [endpoint]}
    second["connect"]["endpoints"] = [endpoint]
    got: list[int] = []
    with zenoh.open(zenoh.Config.from_json5(json.dumps(first))) as a, \
            zenoh.open(zenoh.Config.from_json5(json.dumps(second))) as b:
        sub = b.declare_subscriber("team/**", lambda s: got.append(len(s.payload.to_bytes())))
        deadline = time.monotonic() + 60
        while len(got) < 3 and time.monotonic() < deadline:  # until the route is up
            a.put("team/big", b"x" * 10_000)
            time.sleep(0.2)
        sub.undeclare()
        with open("/proc/self/maps") as f:
            pools = [line for line in f if "/dev/shm/" in line and ".zenoh" in line]
    assert got[:3] == [10_000] * 3
    assert pools == []
