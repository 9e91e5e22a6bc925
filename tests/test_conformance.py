"""The conformance suite: what every registered architecture (`mrta.architectures`) must do, one
test per architecture, parametrized over `mrta_zenoh.architectures.architectures()` — so an
architecture is tested here the day it registers, with no list to edit (tests/README.md).

- its contract attributes are consistent (names, keys, kinds among its messages);
- `mrta arch validate` accepts it; `check_files` accepts every robot of every shipped application
  package configured for it, and refuses a misspelt key naming the file; a package shipped with
  an answers file is what `mrta app new --answers` writes, and `mrta app validate` accepts it;
- its robots' agents, built through the contract (`prepare`, `agent`) from that package's files,
  and the agents of its own processes (`processes`, built by `process_agent` from the package's
  config folder: central's dispatcher), run N ticks in-process (the in-process bus, one manual
  clock, odometry fed as a simulator would): every robot sees its whole team, talks on its
  namespace under its own name with a sequence number per key, and the feed (`read_doing`)
  reads what it said;
- a crash: a robot's agent stops (its token goes); every survivor drops it from its team, a
  survivor takes over its task, and the architecture's `takeover_check` holds for that takeover
  — through the dispatcher's re-plan where there is one.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mrta_agent.runtime.host import AgentOptions
from mrta_zenoh import keys
from mrta_zenoh.architectures import Architecture, Takeover, TakeoverBound, architectures
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.bus.inproc import InProcNetwork
from mrta_zenoh.cli.main import cli
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.codec import encode
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import parse_faults
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_zenoh.toolchain.registry import Registry

ARCHS = architectures()
TICK = 0.1
N = 50  # ticks before anything is checked: 5 simulated seconds
HORIZON = 120.0  # simulated seconds a crash is watched for at most


@pytest.fixture(scope="module")
def registry() -> Registry:
    return Registry()


@dataclasses.dataclass(frozen=True)
class Shipped:
    """One shipped application package configured for an architecture: its robots' files."""

    name: str
    path: Path
    robots: tuple[str, ...]
    stem: str

    @property
    def config(self) -> Path:
        return self.path / "config"

    def robot_params(self, robot: str) -> Path:
        return self.config / f"{robot}_{self.stem}_params.yaml"

    @property
    def tasks_params(self) -> Path:
        return self.config / f"tasks_{self.stem}_params.yaml"

    @property
    def layers_params(self) -> Path:
        return self.config / f"layers_{self.stem}_params.yaml"


def shipped(registry: Registry, arch: Architecture) -> list[Shipped]:
    return sorted((Shipped(pkg.name, pkg.path, tuple(r.id for r in app.robots),
                           arch.param_stem)
                   for pkg, app in registry.applications() if app.architecture == arch.name),
                  key=lambda s: s.name)


def first_package(registry: Registry, arch: Architecture) -> Shipped:
    packages = shipped(registry, arch)
    assert packages, f"no shipped application package is configured for {arch.name}"
    return packages[0]


@pytest.mark.parametrize("name", sorted(ARCHS))
def test_the_contract_attributes_are_consistent(name):
    arch = ARCHS[name]
    assert arch.name == name
    for attr in ("title", "namespace", "executable", "command", "param_stem", "bound_formula"):
        value = getattr(arch, attr)
        assert isinstance(value, str) and value.strip(), f"{name}.{attr} = {value!r}"
    assert re.fullmatch(r"[a-z][a-z0-9_]*", arch.namespace), arch.namespace
    assert arch.messages and all(isinstance(t, type) for t in arch.messages.values())
    for kinds in (arch.doing_kinds, arch.coordination, arch.decision_kinds):
        assert set(kinds) <= set(arch.messages), (kinds, sorted(arch.messages))
    assert arch.doing_kinds, "who is doing what is read from at least one of its messages"
    assert arch.doing_stale_after > 0
    assert isinstance(arch.processes, tuple) and all(isinstance(p, str) for p in arch.processes)
    assert arch.objective in (None, "minsum", "makespan", "flowtime")
    # its keys are its own and say which robot speaks
    for kind in arch.coordination:
        key = arch.key("robot1", kind)
        assert arch.is_coordination_key(key) and arch.is_namespace_key(key)
        assert key.startswith(f"robot1/{arch.namespace}/")
    assert arch.agent_token("robot1") == f"robot1/{arch.namespace}/agent"
    assert not arch.is_namespace_key(arch.agent_token("robot1"))
    # two architectures never share a namespace (their robots would hear each other)
    assert [a.name for a in ARCHS.values() if a.namespace == arch.namespace] == [name]


@pytest.mark.parametrize("name", sorted(ARCHS))
def test_check_files_accepts_the_shipped_packages_and_names_a_misspelt_key(name, registry,
                                                                          tmp_path):
    arch = ARCHS[name]
    for pkg in shipped(registry, arch):
        for robot in pkg.robots:
            arch.check_files(robot, pkg.robot_params(robot), pkg.tasks_params,
                             pkg.layers_params if pkg.layers_params.exists() else None)
    pkg = first_package(registry, arch)
    robot = pkg.robots[0]
    text = pkg.robot_params(robot).read_text()
    key = re.search(r"^([A-Za-z_][A-Za-z0-9_]*):", text, re.MULTILINE)
    assert key, f"no top-level key in {pkg.robot_params(robot)}"
    bad = tmp_path / pkg.robot_params(robot).name
    bad.write_text(text[:key.start()] + key.group(1) + "_typo" + text[key.end(1):])
    with pytest.raises(ConfigError) as err:
        arch.check_files(robot, bad, pkg.tasks_params, None)
    assert bad.name in str(err.value) and key.group(1) in str(err.value)


def mrta(*args: str):
    return CliRunner().invoke(cli, list(args))


@pytest.mark.parametrize("name", sorted(ARCHS))
def test_its_rqt_mrta_package_validates(name):
    res = mrta("arch", "validate", name)
    assert res.exit_code == 0, res.output


@pytest.mark.parametrize("name", sorted(ARCHS))
def test_its_shipped_packages_are_what_their_answers_write_and_validate(name, registry,
                                                                        tmp_path):
    """What `mrta app new --answers` writes is shipped byte for byte (the rest of a package —
    its mission's launch file, the layers' parameters — is written by hand)."""
    for pkg in shipped(registry, ARCHS[name]):
        answers = pkg.path.parent / f"{pkg.name}_answers.yaml"
        if answers.exists():
            out = tmp_path / pkg.name
            res = mrta("app", "new", "--answers", str(answers), "--output", str(out))
            assert res.exit_code == 0, res.output
            written = sorted(f for f in (out / pkg.name).rglob("*") if f.is_file())
            assert written
            for f in written:
                rel = f.relative_to(out / pkg.name)
                assert (pkg.path / rel).read_bytes() == f.read_bytes(), f"{pkg.name}/{rel}"
        res = mrta("app", "validate", pkg.name)
        assert res.exit_code == 0, res.output


class Team:
    """The package's robots, each in its architecture's agent on one in-process network and one
    manual clock, beside the architecture's own processes; every tick each agent takes its
    decision step and its active task's layers run, and every robot moves as its last velocity
    command says (a unicycle with no obstacles, from a point of its own) and is fed the
    odometry a simulator would send. Robots that move serve tasks: a task queued behind
    another (a route architecture's takeover) is reached in the end, and a dispatcher watching
    progress does not take a robot that never moves for a stalled one."""

    def __init__(self, arch: Architecture, pkg: Shipped):
        self.arch, self.package = arch, pkg
        self.clock, self.net = ManualClock(0.0), InProcNetwork()
        self.world = InProcBus(self.net)
        self.said: list[tuple[str, object]] = []
        self.world.subscribe(f"*/{arch.namespace}/**",
                             lambda s: self.said.append((s.key, s.message)))
        self.agents = {}
        self.buses = {}
        self.poses = {robot: [float(k), 0.0, 0.0] for k, robot in enumerate(pkg.robots)}
        self.cmds = {robot: Twist(0.0, 0.0) for robot in pkg.robots}
        for robot in pkg.robots:
            self.world.subscribe(keys.cmd_vel(robot),
                                 lambda s, r=robot: self.cmds.__setitem__(r, s.message),
                                 msg_type=Twist)
        for robot in pkg.robots:
            prepared = arch.prepare(AgentOptions(
                robot, pkg.robot_params(robot), pkg.tasks_params,
                pkg.layers_params if pkg.layers_params.exists() else None))
            self.buses[robot] = InProcBus(self.net)
            agent = arch.agent(prepared, self.buses[robot], self.clock, np.random.default_rng(0))
            agent.start()
            agent.declare_alive()
            self.agents[robot] = agent
        self.processes = {}  # its own processes (a dispatcher), on the team but no robots
        for name in arch.processes:
            self.buses[name] = InProcBus(self.net)
            agent = arch.process_agent(name, pkg.config, self.buses[name], self.clock,
                                       np.random.default_rng(0))
            agent.start()
            agent.declare_alive()
            self.processes[name] = agent
        self.seq = 0

    def tick(self, n: int = 1, watch=None) -> None:
        for _ in range(n):
            self.seq += 1
            now = self.clock.now()
            for robot in self.agents:
                self.world.publish(keys.odom(robot), Odometry(
                    Header(robot, now, self.seq), Pose2D(*self.poses[robot]),
                    self.cmds[robot]))
            for agent in self.members():
                agent.tick_high(now)
                agent.step_layers(now, TICK)
            if watch is not None:
                watch(now)
            for robot in self.agents:
                self.move(robot)
            self.clock.advance(TICK)

    def move(self, robot: str) -> None:
        """One step of `robot`'s body under its last command."""
        pose, cmd = self.poses[robot], self.cmds[robot]
        pose[0] += cmd.linear * math.cos(pose[2]) * TICK
        pose[1] += cmd.linear * math.sin(pose[2]) * TICK
        pose[2] = math.remainder(pose[2] + cmd.angular * TICK, math.tau)

    def members(self) -> list:
        """Every agent still running: the robots', then the processes'."""
        return [*self.agents.values(), *self.processes.values()]

    def crash(self, robot: str) -> None:
        """`robot`'s agent is gone, as after SIGKILL: it says nothing more, its token goes."""
        self.agents.pop(robot)
        self.buses.pop(robot).close()

    def close(self) -> None:
        for agent in self.members():
            agent.shutdown()
        for bus in self.buses.values():
            bus.close()
        self.world.close()


@pytest.fixture
def team(request, registry):
    arch = ARCHS[request.param]
    t = Team(arch, first_package(registry, arch))
    yield t
    t.close()


@pytest.mark.parametrize("team", sorted(ARCHS), indirect=True)
def test_the_robots_run_n_ticks_in_process_and_say_who_they_are(team):
    arch = team.arch
    team.tick(N)
    robots = set(team.agents)
    processes = set(team.processes)
    for robot, agent in team.agents.items():
        assert agent.team == (robots | processes) - {robot}, robot
    for name, agent in team.processes.items():
        assert agent.team == robots, name
    assert team.said, f"{arch.name}'s robots said nothing in {N} ticks"
    speakers = {first_chunk(key) for key, _ in team.said}
    assert speakers <= robots | processes
    assert speakers & robots, f"{arch.name}'s robots said nothing in {N} ticks"
    last: dict[str, int] = {}
    for key, message in team.said:
        header = message.header
        assert header.frame_id == first_chunk(key), (key, header)
        assert header.seq > last.get(key, 0), (key, header.seq, last.get(key))
        last[key] = header.seq
        assert 0.0 <= header.stamp <= team.clock.now()
    feed = [arch.read_doing(key, m) for key, m in team.said
            if key.split("/")[2] in arch.doing_kinds]
    assert feed, f"nothing {arch.name}'s robots said is on its feed ({arch.doing_kinds})"
    assert all(d.robot in robots for d in feed if d is not None)


@pytest.mark.parametrize("team", sorted(ARCHS), indirect=True)
def test_a_crashed_robot_leaves_every_team_and_its_task_is_taken_within_the_check(team):
    arch = team.arch
    team.tick(N)
    held = {robot: agent.active_task for robot, agent in team.agents.items()
            if agent.active_task is not None}
    assert held, f"no robot of {arch.name} holds a task after {N} ticks"
    failed, task = sorted(held.items())[0]
    failed_at = team.clock.now()
    team.crash(failed)
    taken: list[tuple[float, str]] = []

    def watch(now):
        if not taken:
            taken.extend((now, r) for r, a in sorted(team.agents.items()) if a.active_task == task)

    for _ in range(int(HORIZON / TICK)):  # a bounded wait: whether the take is in time is the check's
        team.tick(1, watch)
        if taken and not any(failed in a.team for a in team.members()):
            break
    for agent in team.members():
        assert failed not in agent.team, agent.robot_id
    assert taken, f"nobody took {task} over from {failed} under {arch.name}"
    taken_at, taker = taken[0]
    records = [(key, "", int(round(m.header.stamp * 1e9)), encode(m)) for key, m in team.said]
    check = arch.takeover_check(Takeover(
        task, failed, failed_at, taker, taken_at, team.package.robot_params(taker), records,
        lambda ns: ns / 1e9, parse_faults("crash:%s@%g" % (failed, failed_at)), 0, True))
    assert isinstance(check, TakeoverBound)
    assert check.since <= taken_at
    assert check.holds(taken_at) is not False, (arch.name, check, taken_at)

