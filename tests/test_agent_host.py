"""The agent host's pure parts: its loop (`drive`) on a clock that moves by physics steps, the
seats it accepts, the spec `mrta host` reads, and how the mission runner regroups a launch's
agent nodes into hosts. The whole host on real processes: tests/process/test_hosts_identity.py."""

import dataclasses
import math
import threading

import pytest
import yaml
from click.testing import CliRunner

from mrta_agent.runtime.agent_host import Crashed, Seat, check_seats, drive, refuse_secured
from mrta_agent.runtime.host import AgentOptions
from mrta_supervisor.mission.hosting import HOST_EXECUTABLE, hosted_crash, host_nodes
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.main import cli
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.toolchain.launchfile import NodeSpec

STEP = 0.02


class StepClock(ManualClock):
    """Lockstep as a host sees it: a sleep ends at the first physics step at or after its time."""

    def sleep_until(self, t, stop=None):
        self.set(max(self.now(), math.ceil(round(t / STEP, 6)) * STEP))
        return True


class FakeAgent:
    """An agent whose schedule ticks every `period`, recording when (and in which order, in the
    shared `log`) it was resumed; it crashes at `crash_at`."""

    def __init__(self, robot_id, period, log, clock, crash_at=None, alive=None):
        self.robot_id, self.period, self.log, self.clock = robot_id, period, log, clock
        self.crash_at, self.withdrawn = crash_at, False
        self.alive = alive if alive is not None else set()

    def schedule(self, until=None):
        t = 0.0
        while until is None or t <= until:
            yield t
            now = self.clock.now()
            if self.crash_at is not None and now >= self.crash_at:
                raise Crashed(self.robot_id)
            self.log.append((round(now, 6), self.robot_id))
            t += self.period

    def withdraw(self):
        self.withdrawn = True
        self.alive.discard(self.robot_id)

    def hears_alive(self, robot):
        return robot in self.alive


def test_a_host_resumes_each_robot_at_its_own_times_in_id_order():
    clock, log = StepClock(), []
    agents = [FakeAgent("robot2", 0.1, log, clock), FakeAgent("robot1", 0.05, log, clock)]
    drive(agents, clock, threading.Event(), until=0.2)
    # robot1's 0.05 falls between physics steps: resumed at 0.06, as its own process would be
    assert log == [(0.0, "robot1"), (0.0, "robot2"), (0.06, "robot1"), (0.1, "robot1"),
                   (0.1, "robot2"), (0.16, "robot1"), (0.2, "robot1"), (0.2, "robot2")]


def test_a_crash_withdraws_that_robot_only_and_the_others_go_on():
    clock, log = StepClock(), []
    alive = {"robot1", "robot2", "robot3"}
    agents = [FakeAgent(r, 0.1, log, clock, crash_at=0.3 if r == "robot2" else None,
                        alive=alive) for r in ("robot1", "robot2", "robot3")]
    drive(agents, clock, threading.Event(), until=0.5)
    assert agents[1].withdrawn and not agents[0].withdrawn and not agents[2].withdrawn
    assert max(t for t, r in log if r == "robot2") == pytest.approx(0.2)
    assert max(t for t, r in log if r == "robot3") == pytest.approx(0.5)
    assert alive == {"robot1", "robot3"}


def test_a_stop_ends_the_host_loop():
    clock, stop = StepClock(), threading.Event()
    stop.set()
    log = []
    drive([FakeAgent("robot1", 0.1, log, clock)], clock, stop)
    assert log == []


def _seat(robot, **kw):
    return Seat(AgentOptions(robot, "r.yaml", "t.yaml", sim_time=True, **kw), None, "x")


def test_seats_must_share_clock_seed_and_duration_and_be_distinct():
    check_seats([_seat("robot1"), _seat("robot2")])
    with pytest.raises(ConfigError, match="robot1 given twice"):
        check_seats([_seat("robot1"), _seat("/robot1")])
    with pytest.raises(ConfigError, match="robot2's seed is 4"):
        check_seats([_seat("robot1"), _seat("robot2", seed=4)])
    with pytest.raises(ConfigError, match="at least one robot"):
        check_seats([])


def test_a_secured_fleet_is_refused(tmp_path):
    refuse_secured(BusOptions())  # an open bus: nothing to refuse
    out = tmp_path / "fleet"
    result = CliRunner().invoke(cli, ["secure", "init", str(out), "--robot", "robot1"])
    assert result.exit_code == 0, result.output
    config = next(out.rglob("robot1.json5"))
    with pytest.raises(ConfigError, match="open bus only"):
        refuse_secured(BusOptions(zenoh_config=config))


def _spec(tmp_path, agents, name="host1"):
    spec = tmp_path / "host.yaml"
    spec.write_text(yaml.safe_dump({"name": name, "agents": agents}))
    return spec


@pytest.mark.parametrize("agents, message", [
    ([["sssi", "robot1"]], "'sssi' is no architecture's agent verb (did you mean 'ssi'?)"),
    ([["ssi", "robot1", "--robot-params", "a", "--tasks-params", "b", "--connect",
       "tcp/127.0.0.1:1"]], "bus options belong to the host's command line"),
    ([["ssi", "robot1", "--bogus"]], "No such option '--bogus'"),
    ([["ssi"]], "expected [ARCHITECTURE_VERB, ROBOT_ID, options…]"),
])
def test_a_bad_spec_is_one_line_and_exit_2(tmp_path, agents, message):
    result = CliRunner().invoke(cli, ["host", str(_spec(tmp_path, agents))])
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert "host.yaml:" in result.output and len(result.output.splitlines()) == 1


def test_an_unknown_key_in_the_spec_names_its_line(tmp_path):
    spec = tmp_path / "host.yaml"
    spec.write_text("name: host1\nagent:\n  - [ssi, robot1]\n")
    result = CliRunner().invoke(cli, ["host", str(spec)])
    assert result.exit_code == 2 and "host.yaml:2" in result.output
    assert "did you mean 'agents'" in result.output


def _nodes():
    nodes = [NodeSpec("sim", "simulator", "sim", ["--world", "delivery"], required=True)]
    nodes += [NodeSpec(f"robot{i}/ssi", "ssi", "agent", [f"robot{i}", "--sim-time"],
                       env={"MRTA_TEAM": "robot1,robot2,robot3"}) for i in (1, 2, 3)]
    nodes.append(NodeSpec("dispatcher", "central", "dispatcher", []))
    return nodes


def test_the_runner_regroups_agent_nodes_k_per_host(tmp_path):
    nodes, where = host_nodes(_nodes(), ["robot1", "robot2", "robot3"], 2, tmp_path)
    assert [n.name for n in nodes] == ["sim", "host1", "host2", "dispatcher"]
    assert where == {"robot1": "host1", "robot2": "host1", "robot3": "host2"}
    host1 = nodes[1]
    assert host1.executable == HOST_EXECUTABLE and host1.env == {"MRTA_TEAM": "robot1,robot2,robot3"}
    spec = yaml.safe_load((tmp_path / "host1.yaml").read_text())
    assert spec == {"name": "host1", "agents": [["ssi", "robot1", "--sim-time"],
                                                ["ssi", "robot2", "--sim-time"]]}


def test_a_node_equal_to_a_hosted_agent_node_is_not_taken_for_it(tmp_path):
    """The runner replaces the agent nodes it hosts by identity: a second node equal to one of
    them field for field (a launch file that names it twice) is not silently dropped with it."""
    nodes = _nodes()
    twin = dataclasses.replace(nodes[1])
    assert twin == nodes[1] and twin is not nodes[1]
    out, _ = host_nodes([*nodes, twin], ["robot1", "robot2", "robot3"], 3, tmp_path)
    assert [n.name for n in out] == ["sim", "host1", "dispatcher", "robot1/ssi"]
    assert out[-1] is twin


def test_robots_of_one_host_must_share_its_environment(tmp_path):
    nodes = _nodes()
    nodes[2].env = {"MRTA_TEAM": "robot2"}
    with pytest.raises(ConfigError, match="share its environment"):
        host_nodes(nodes, ["robot1", "robot2", "robot3"], 3, tmp_path)


class _Child:
    def __init__(self, lines):
        self.stdout = lines


def test_a_hosted_crash_is_told_by_its_hosts_line_for_that_robot_only():
    child = _Child(["12:00 WARNING mrta.agent: robot10: crashing at t=10.00 as asked"])
    assert hosted_crash(child, "robot10") and not hosted_crash(child, "robot1")
    assert not hosted_crash(None, "robot10")


def test_a_host_reads_the_files_its_robots_share_once(tmp_path, monkeypatch):
    """The instance, tasks and layers files every robot of a package names are parsed once per
    host (mrta_zenoh.shared_reads), each robot's own file once per robot; every robot still
    gets its own tasks dict (a robot may grow its tasks) and the same frozen problem."""
    from pathlib import Path

    import mrta_agent.route.own_route_params as own
    from mrta_agent.runtime import host_cli
    from mrta_zenoh import instances, yamlfile

    config = Path(__file__).resolve().parents[1] / "configs/applications/delivery_cbba/config"
    parsed, made = [], []
    real_parse = yamlfile.parse_yaml

    def counting(text, path, *a, **kw):
        parsed.append(Path(path).name)
        return real_parse(text, path, *a, **kw)

    monkeypatch.setattr(yamlfile, "parse_yaml", counting)
    real_load = own.load_params
    monkeypatch.setattr(own, "load_params", lambda *a: made.append(real_load(*a)) or made[-1])
    robots = ["robot1", "robot2", "robot3"]
    spec = _spec(tmp_path, [["cbba", r, "--robot-params", str(config / f"{r}_cbba_params.yaml"),
                             "--tasks-params", str(config / "tasks_cbba_params.yaml"),
                             "--layers-params", str(config / "layers_cbba_params.yaml"),
                             "--sim-time"] for r in robots])
    _, seats = host_cli.read_spec(spec)
    assert [s.options.robot_id for s in seats] == robots
    shared = ["instance.yaml", "tasks_cbba_params.yaml", "layers_cbba_params.yaml"]
    assert sorted(n for n in parsed if n in shared) == sorted(shared)
    assert sorted(n for n in parsed if n.startswith("robot")) == \
        sorted(f"{r}_cbba_params.yaml" for r in robots)
    assert len(made) == 3 and made[0].problem is made[1].problem is made[2].problem
    assert made[0].tasks == made[1].tasks and made[0].tasks is not made[1].tasks
    # outside a host nothing is remembered: a robot's own process reads as before
    parsed.clear()
    instances.load(config / "instance.yaml")
    instances.load(config / "instance.yaml")
    assert parsed == ["instance.yaml", "instance.yaml"]


def test_the_runner_starts_the_robots_with_the_recorder_and_the_simulator_once_it_is_up():
    """Start-up at once, readiness by tokens (runner._start_up): every robot's process starts
    before the recorder is up, the simulator only once its token is heard."""
    from mrta_supervisor.mission.run_watch import Readiness
    from mrta_supervisor.mission.runner import _start_up
    from mrta_zenoh import keys
    from mrta_zenoh.bus import InProcBus

    bus = InProcBus()
    started = []

    class Group:
        def start(self, argv, name, env=None, merge_stderr=False):
            started.append((name, ready.recorder.is_set()))
            if name == "host1":  # the recorder comes up while the robots start
                threading.Timer(0.05, bus.declare_token,
                                [f"{keys.RECORDER_TOKEN}/rec"]).start()
            return name

        def failed(self, ignore=()):
            return []

    nodes = [NodeSpec("sim", "simulator", "sim", [], required=True),
             NodeSpec("host1", "robot_agent", "host", []),
             NodeSpec("dispatcher", "robot_agent", "central", [])]
    with Readiness(bus, ["robot1"]) as ready:
        children = _start_up(nodes, Group(), ready, None, threading.Event())
    assert children == ["sim", "host1", "dispatcher"]  # the launch's order
    assert started == [("host1", False), ("dispatcher", False), ("sim", True)]
    bus.close()


def test_a_process_is_given_longer_to_come_up_on_a_busy_machine():
    """The runner's start-up wait stretches with the load per core (run_watch.ready_timeout):
    on an idle machine READY_TIMEOUT, at 15 runnable processes a core 15 times that."""
    from mrta_supervisor.mission.run_watch import READY_TIMEOUT, ready_timeout

    assert ready_timeout(0.3, 2) == ready_timeout(2.0, 2) == READY_TIMEOUT
    assert ready_timeout(30.0, 2) == 15 * READY_TIMEOUT
    assert ready_timeout(30.0, 0) == 30 * READY_TIMEOUT
