"""A mission's processes as an operator meets them: children that never outlive `mrta demo`
(even after a kill -9), an output folder one run at a time, a default failure that fits the
run's duration."""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import time
from pathlib import Path

import pytest

from mrta_supervisor.mission.hook import MissionOptions, resolve
from mrta_supervisor.mission.runner import output_lock
from mrta_zenoh.errors import ConfigError


def children_of(pid: int) -> set[int]:
    """Live processes whose parent is `pid` (from /proc: no psutil needed)."""
    out = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == pid and fields[0] != "Z":
            out.add(int(entry.name))
    return out


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_the_default_failure_fits_the_duration():
    """The default failure scales with the duration: at a fixed 30 s, `mrta demo --duration 20`
    would exit 2."""
    for duration, spec in ((20.0, "robot2@10"), (60.0, "robot2@30"), (7.0, "robot2@3.5")):
        f = resolve(MissionOptions(duration=duration)).faults.primary
        assert (f.robot, f.at, f.spec) == ("robot2", float(spec.split("@")[1]), spec)
    with pytest.raises(ConfigError, match="not before the end"):
        resolve(MissionOptions(duration=10.0, fail="robot2@10"))


def test_an_output_folder_in_use_is_refused_and_freed_when_its_run_ends(tmp_path):
    with output_lock(tmp_path):
        with pytest.raises(ConfigError, match=f"in use by another run \\(pid {os.getpid()}\\)"):
            with output_lock(tmp_path):
                pass
    with output_lock(tmp_path):  # released: the next run may write there
        pass


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(150)
def test_a_second_demo_in_the_same_folder_is_refused(children, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    stale = out / "motivation_robot9_wander.png"  # an earlier run's, from a clock ahead of ours
    stale.write_bytes(b"old")
    os.utime(stale, (time.time() + 3600, time.time() + 3600))
    first = children.mrta("-q", "demo", "--duration", "8", "--speed", "1", "--fail", "none",
                          "--no-live", "--output", out, name="first")
    deadline = time.monotonic() + 60
    while not (out / ".mrta-run.lock").exists() or not children_of(first.proc.pid):
        assert time.monotonic() < deadline and first.proc.poll() is None, first.tail()
        time.sleep(0.1)
    second = children.mrta("-q", "demo", "--duration", "12", "--speed", "0", "--no-live",
                           "--output", out, name="second")
    assert second.wait(60) == 2
    assert any("in use by another run" in line for line in second.stderr), second.stderr
    assert first.wait(100) == 0, first.tail(20)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["duration"] == 8.0 and summary["speed"] == 1.0  # the first run's, whole
    # exactly the files this run wrote, summary.json included, on one line even in a pipe
    assert stale.name not in summary["files"] and "summary.json" in summary["files"]
    assert {"run.mcap", "world.png", "timeline.png"} <= set(summary["files"])
    (files,) = [line for line in first.stdout if line.startswith("  files in ")]
    assert files == f"  files in {out}: {', '.join(summary['files'])}", first.stdout
    # -q: no progress lines, only the summary
    assert not any(line.startswith("t=") for line in first.stdout), first.stdout
    assert first.stderr == [], first.stderr  # nor warnings: a quiet success says nothing there
    assert first.stdout[1].startswith("Patrol mission (ALLIANCE): 8 s simulated"), first.stdout


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_kill_9_of_the_demo_leaves_no_process_behind(children, tmp_path):
    """The simulator, the agents and the recorder notice their parent is gone and stop."""
    demo = children.mrta("-q", "demo", "--duration", "600", "--speed", "1", "--no-live",
                         "--output", tmp_path / "out", name="demo")
    deadline = time.monotonic() + 60
    kids: set[int] = set()
    while len(kids) < 5:  # the recorder, the simulator and three agents
        assert time.monotonic() < deadline and demo.proc.poll() is None, demo.tail()
        time.sleep(0.2)
        kids = children_of(demo.proc.pid)
    time.sleep(2.0)  # let them get going: not readiness, part of the scenario
    os.kill(demo.proc.pid, signal.SIGKILL)
    demo.wait(10)
    deadline = time.monotonic() + 30  # the watcher polls every 0.5 s; a clean stop takes a few s
    while any(alive(p) for p in kids) and time.monotonic() < deadline:
        time.sleep(0.2)
    left = [p for p in kids if alive(p)]
    for p in left:  # ours to end, by PID, so nothing outlives the test even if it fails
        os.kill(p, signal.SIGKILL)
    assert not left, f"{len(left)} of {len(kids)} children outlived a kill -9 of the demo"


@pytest.mark.parametrize("package", ["patrol", "patrol_murdoch", "delivery", "delivery_murdoch"])
def test_every_node_of_a_mission_gets_the_runs_seed_from_the_runner_not_from_its_args(package):
    """The seed reaches every process as $MRTA_SEED (the runner's environment, and the launch
    file's own `<env>` for `mrta launch … seed:=S`), never as `--seed` text a node could lack."""
    from mrta_zenoh.seeds import SEED_ENV
    from mrta_zenoh.toolchain.launchfile import LaunchEvaluator
    from mrta_zenoh.toolchain.registry import Registry

    from mrta_supervisor.mission.runner import check_seeds

    reg = Registry()
    launch = reg.find(package).path / "launch" / ("patrol_sim.launch" if "patrol" in package
                                                  else "delivery_sim.launch")
    nodes = LaunchEvaluator(lambda n: reg.find(n).path).run(launch, {"seed": "7"})
    assert len(nodes) >= 4
    for n in nodes:
        assert "--seed" not in " ".join(n.args), n.name
        assert n.env[SEED_ENV] == "7", n.name
    check_seeds(nodes, 7)
    with pytest.raises(ConfigError, match=f"node {nodes[0].name} is given seed '7', but the "
                                          "run's seed is 3"):
        check_seeds(nodes, 3)


def test_a_node_given_another_seed_by_its_launch_file_is_refused():
    from mrta_supervisor.mission.runner import check_seeds
    from mrta_zenoh.toolchain.launchfile import NodeSpec

    def node(*args, **env):
        return NodeSpec("robot1/alliance", "robot_agent", "agent", list(args), env=env,
                        file="x.launch", line=4)

    check_seeds([node("robot1", "--sim-time"), node("--seed", "3"), node("--seed=3")], 3)
    for bad in (node("robot1", "--seed", "0"), node("--seed=0"), node(MRTA_SEED="0")):
        with pytest.raises(ConfigError, match="x.launch:4: node robot1/alliance is given seed "
                                              "'0', but the run's seed is 3"):
            check_seeds([bad], 3)


def test_a_launch_without_a_required_node_is_refused_naming_the_file():
    """A mission run ends when its launch's required node (the simulator) ends: a launch with
    none is bad input before anything starts, not a StopIteration once the processes are up."""
    from mrta_supervisor.mission.runner import check_end
    from mrta_zenoh.toolchain.launchfile import NodeSpec

    sim = NodeSpec("sim", "simulator", "sim", [], required=True)
    agent = NodeSpec("robot1/alliance", "robot_agent", "agent", [])
    check_end([agent, sim], Path("x.launch"))
    with pytest.raises(ConfigError, match=r"x\.launch: no node is required=\"true\""):
        check_end([agent, dataclasses.replace(sim, required=False)], Path("x.launch"))



def test_a_launch_without_the_architectures_own_process_is_refused_naming_it():
    """A central launch with no dispatcher node ran its robots idle the whole run (issue 51, a
    wizard's patrol package): refused before anything starts, naming the process."""
    from mrta_supervisor.mission.runner import check_end
    from mrta_zenoh.toolchain.launchfile import NodeSpec

    sim = NodeSpec("sim", "simulator", "sim", [], required=True)
    agent = NodeSpec("robot1/central", "central", "agent", [])
    dispatcher = NodeSpec("dispatcher", "central", "dispatcher", [])
    check_end([agent, dispatcher, sim], Path("x.launch"), ("dispatcher",))
    with pytest.raises(ConfigError, match=r"x\.launch: no node named dispatcher: the "
                                          r"architecture's own process"):
        check_end([agent, sim], Path("x.launch"), ("dispatcher",))
