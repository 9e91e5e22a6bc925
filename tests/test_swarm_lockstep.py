"""A generated N-robot application (benchmarks/swarm.py: patrol's tasks, N robots, made through
the toolchain's build_application) runs in lockstep with every agent joining the barrier from
step 0, and the lockstep books' memory of which subscriptions count a key follows
the bus's subscriptions."""

import importlib.util
import re
from pathlib import Path

import pytest
import yaml

from mrta_zenoh.bus.inproc import InProcBus
from mrta_zenoh.lockstep.books import Books
from mrta_zenoh.lockstep.table import Claims, KeyTable
from mrta_zenoh.messages import Clock

ROOT = Path(__file__).resolve().parent.parent
N = 6


def swarm_module():
    spec = importlib.util.spec_from_file_location("swarm_bench", ROOT / "benchmarks" / "swarm.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_generated_package_has_every_robot_with_patrol_parameters(tmp_path):
    swarm = swarm_module()
    config, world, robots = swarm.generate(N, tmp_path)
    assert robots == [f"robot{k + 1}" for k in range(N)]
    starts = yaml.safe_load(world.read_text())["robots"]
    assert sorted(starts) == sorted(robots)
    assert len({tuple(p[:2]) for p in starts.values()}) == N  # no two robots on one start
    patrol = ROOT / "configs" / "applications" / "patrol" / "config"
    for k, r in enumerate(robots):
        mine = yaml.safe_load((config / f"{r}_alliance_params.yaml").read_text())
        theirs = yaml.safe_load((patrol / f"robot{k % 3 + 1}_alliance_params.yaml").read_text())
        assert mine["behaviour_sets"] == theirs["behaviour_sets"]


def test_a_task_subset_keeps_the_matching_behaviour_sets(tmp_path):
    swarm = swarm_module()
    config, _, _ = swarm.generate(3, tmp_path, ("wander", "border_protection"))
    sets = yaml.safe_load((config / "robot1_alliance_params.yaml").read_text())["behaviour_sets"]
    assert sets["size"] == 2
    assert [sets[f"behaviour_set{i}"]["task_id"] for i in range(2)] == \
        ["wander", "border_protection"]


def test_books_memory_follows_the_subscriptions():
    """A key no subscription matched is waited for once a subscription that matches it comes."""
    with InProcBus() as bus:
        books, table = Books(bus.enable_counting()), KeyTable()
        table.add({"robot2/clock"})
        step = Claims(table, [3])
        bus.subscribe("robot1/clock", lambda s: None, msg_type=Clock)
        assert books.missing(step) == {}
        sub = bus.subscribe("*/clock", lambda s: None, msg_type=Clock)
        assert books.missing(step) == {"robot2/clock": 3}
        sub.close()
        assert books.missing(step) == {}


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(170)
def test_n_generated_robots_run_in_lockstep_and_every_agent_joins(children, tmp_path):
    swarm = swarm_module()
    config, world, robots = swarm.generate(N, tmp_path)
    children.env["MRTA_TEAM"] = ",".join(robots)
    agents = [children.mrta("-q", "agent", r,
                            "--robot-params", config / f"{r}_alliance_params.yaml",
                            "--tasks-params", config / "tasks_alliance_params.yaml",
                            "--layers-params", config / "layers_alliance_params.yaml",
                            "--sim-time", name=r) for r in robots]
    sim = children.mrta("sim", "--world", world, *[a for r in robots for a in ("--robot", r)],
                        "--speed", "0", "--duration", "5", "--lockstep", "--wait-robots", "90",
                        name="sim")
    assert sim.wait(150) == 0, sim.stderr[-20:]
    ready = next(line for line in sim.stderr if "ready:" in line)
    assert f"lockstep with {N} participants" in ready, ready
    done = next(line for line in sim.stderr if "done:" in line)
    assert float(re.search(r"done: ([\d.]+) s simulated", done).group(1)) >= 5.0 - 0.05
    assert not any("no longer waited for" in line for line in sim.stderr), sim.stderr[-20:]
    assert all(a.running() for a in agents)  # none crashed while the run went on
