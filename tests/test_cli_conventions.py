"""The command line behaves like its neighbours, on pure logic: how a child's end is named and judged, roslaunch's policy for nodes that end,
Ctrl-C → 130, "did you mean" for commands, help texts, JSON numbers, field paths and topic
names as ROS users type them, relative times, and log lines that cannot drive a terminal."""

from __future__ import annotations

import io
import json
import logging
import os
import signal
import subprocess
import sys
import threading

import click
import pytest
from click.testing import CliRunner
from rich.console import Console

from mrta_zenoh import jsonsafe
from mrta_zenoh.cli.common import SafeFormatter, plural
from mrta_zenoh.cli.echo import key_of
from mrta_zenoh.cli.main import cli, run
from mrta_zenoh.fieldpath import FieldPath, FieldPathError
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.processes import Child, ProcessGroup, describe_returncode
from mrta_zenoh.toolchain import runner
from mrta_zenoh.toolchain.launchfile import NodeSpec


# ------------------------------------------------------------------ children, without processes
class FakeProc:
    """A Popen stand-in: `rc` is None while "running"; a signal ends it with `on_signal[sig]`
    (default: killed by it, -sig)."""

    def __init__(self, pid: int, on_signal: dict[int, int] | None = None):
        self.pid, self.rc, self.on_signal = pid, None, on_signal or {}

    def poll(self):
        return self.rc

    def wait(self, timeout=None):
        if self.rc is None:
            raise subprocess.TimeoutExpired("fake", timeout)
        return self.rc


class FakeChild(Child):
    def __init__(self, name: str, on_signal: dict[int, int] | None = None):
        # Child.__init__ would start a process: set what the rest of Child reads
        self.name, self.argv = name, [name]
        self.proc = FakeProc(1000 + len(name), on_signal)
        self.stdout, self.stderr, self.signalled, self._threads = [], [], set(), []

    def signal(self, sig: int) -> None:
        if self.proc.rc is None:
            self.signalled.add(sig)
            self.proc.rc = self.proc.on_signal.get(sig, -sig)

    def end(self, rc: int) -> None:  # it ends by itself (or by someone else's signal)
        self.proc.rc = rc


def test_a_childs_end_is_named_as_people_say_it():
    assert describe_returncode(0) == "exited normally"
    assert describe_returncode(3) == "exited with code 3"
    assert describe_returncode(-signal.SIGKILL) == "killed by SIGKILL"
    assert describe_returncode(-signal.SIGINT) == "killed by SIGINT"


@pytest.mark.parametrize("rc,ours,failed,text", [
    (-signal.SIGKILL, set(), True, "killed by SIGKILL"),       # a kill -9 from outside
    (2, set(), True, "exited with code 2"),
    (0, set(), False, "exited normally"),
    (-signal.SIGINT, {signal.SIGINT}, False, "stopped"),       # by our SIGINT (or the terminal's)
    (130, {signal.SIGINT}, False, "stopped"),                  # caught it: Ctrl-C's 130
    (0, {signal.SIGINT}, False, "stopped"),
    (-signal.SIGKILL, {signal.SIGINT, signal.SIGKILL}, False, "stopped"),  # our escalation
    (1, {signal.SIGINT}, True, "exited with code 1"),          # crashed while stopping
    (-signal.SIGKILL, {signal.SIGINT}, True, "killed by SIGKILL"),
])
def test_only_an_end_we_asked_for_is_not_a_failure(rc, ours, failed, text):
    c = FakeChild("sim")
    c.end(rc)
    c.signalled |= ours
    assert c.failed() is failed and c.describe_exit() == text
    group = ProcessGroup()
    group.children.append(c)
    assert group.failed() == ([c] if failed else [])


def test_after_ctrl_c_a_child_ended_by_the_terminals_sigint_was_stopped():
    """The terminal sends SIGINT to the whole process group: the simulator may be gone before
    the launch signals it. That is no "exited with code -2"."""
    group = ProcessGroup()
    sim = FakeChild("sim")
    group.children.append(sim)
    sim.end(-signal.SIGINT)
    assert sim.describe_exit() == "killed by SIGINT"  # before anyone knew of a Ctrl-C
    group.interrupted()
    assert sim.describe_exit() == "stopped" and group.failed() == []


# ------------------------------------------------------------------ roslaunch's policy
def node(name: str, required: bool = False) -> NodeSpec:
    return NodeSpec(name=name, pkg="simulator", type="sim", args=[], required=required)


@pytest.fixture
def fake_launch(monkeypatch):
    """run_nodes over FakeChildren: returns (children by name, the lines it said)."""
    made: dict[str, FakeChild] = {}

    def start_nodes(group, nodes):
        kids = [made.setdefault(n.name, FakeChild(n.name, {signal.SIGINT: 130})) for n in nodes]
        group.children.extend(kids)
        return kids

    monkeypatch.setattr(runner, "start_nodes", start_nodes)
    return made


def test_a_required_node_killed_from_outside_brings_the_launch_down(fake_launch):
    lines: list[str] = []
    fake_launch["sim"] = FakeChild("sim")
    fake_launch["sim"].end(-signal.SIGKILL)  # kill -9 of the simulator
    result = runner.run_nodes([node("sim", required=True), node("robot1/agent")],
                              threading.Event(), echo=lines.append)
    assert result.brought_down_by == "sim" and result.failed == ["sim killed by SIGKILL"]
    assert lines[0].startswith("[sim] killed by SIGKILL — a required node")
    assert lines[1:] == ["[robot1/agent] stopped"] and not result.interrupted


def test_a_node_that_is_not_required_is_reported_and_the_others_keep_running(fake_launch):
    stop = threading.Event()
    lines: list[str] = []

    def said(line: str) -> None:
        lines.append(line)
        if line.startswith("[robot1/agent]"):
            assert fake_launch["sim"].running()  # still running after the agent's death
            stop.set()                           # … until the user presses Ctrl-C

    fake_launch["robot1/agent"] = FakeChild("robot1/agent")
    fake_launch["robot1/agent"].end(-signal.SIGKILL)
    result = runner.run_nodes([node("sim"), node("robot1/agent")], stop, echo=said)
    assert lines == ["[robot1/agent] killed by SIGKILL", "[sim] stopped"]
    assert result.failed == ["robot1/agent killed by SIGKILL"] and result.interrupted
    assert result.brought_down_by is None


def test_the_launch_ends_when_every_node_has_ended(fake_launch):
    for name, rc in (("a", 0), ("b", 0)):
        fake_launch[name] = FakeChild(name)
        fake_launch[name].end(rc)
    lines: list[str] = []
    result = runner.run_nodes([node("a"), node("b")], threading.Event(), echo=lines.append)
    assert lines == ["[a] exited normally", "[b] exited normally"] and result.failed == []


def test_ctrl_c_stops_every_node_and_none_is_a_failure(fake_launch):
    stop = threading.Event()
    stop.set()
    fake_launch["sim"] = FakeChild("sim")
    fake_launch["sim"].end(-signal.SIGINT)  # the terminal's SIGINT got there first
    lines: list[str] = []
    result = runner.run_nodes([node("sim"), node("robot1/agent")], stop, echo=lines.append)
    assert result.interrupted and result.failed == []
    assert sorted(lines) == ["[robot1/agent] stopped", "[sim] stopped"]


# ------------------------------------------------------------------ exit codes, commands
@click.command()
@click.argument("sig", type=int)
def _stopped_by(sig: int) -> None:
    with stop_on_signals() as stop:
        os.kill(os.getpid(), sig)  # our own handler: it only sets `stop`
        assert stop.wait(5)


def test_a_run_ended_by_ctrl_c_exits_130_and_one_ended_by_sigterm_exits_0():
    """Ctrl-C exits 130 even though the agent shuts down cleanly and returns."""
    assert run(_stopped_by, [str(int(signal.SIGINT))]) == 130
    assert run(_stopped_by, [str(int(signal.SIGTERM))]) == 0


def test_a_mistyped_command_gets_a_suggestion():
    res = CliRunner().invoke(cli, ["dmeo"])
    assert res.exit_code == 2 and "No such command 'dmeo'. Did you mean 'demo'?" in res.output


def test_help_texts_say_whole_sentences_and_the_router_offers_only_router_options():
    from mrta_zenoh.cli.echo import echo
    short = echo.get_short_help_str(limit=64)  # what `mrta --help` lists (80 columns)
    assert short == "Print the samples on a key expression or ROS topic.", short
    router = CliRunner().invoke(cli, ["router", "--help"]).output
    assert "--mode" not in router and "--namespace" not in router
    assert "127.0.0.1:0" not in router and "tcp/127.0.0.1:7447" in router


def test_counts_read_as_english():
    assert [plural(n, "robot") for n in (0, 1, 2)] == ["0 robots", "1 robot", "2 robots"]
    with pytest.raises(FieldPathError, match=r"a list of 1 item: use an index"):
        FieldPath.parse("points/x").resolve({"points": [1]})


# ------------------------------------------------------------------ what ROS users type
def test_a_ros_topic_name_names_its_key():
    assert key_of("/robot1/odom") == "robot1/odom"
    assert key_of("robot1/**") == "robot1/**" and key_of("/") == "/"


@pytest.mark.parametrize("text", ["header/frame_id", "/header/frame_id", "header.frame_id"])
def test_dotted_and_slashed_field_paths_are_the_same_path(text):
    assert FieldPath.parse(text).steps == ("header", "frame_id")


@pytest.mark.parametrize("text", ["points/0/x", "points.0.x", "points[0].x", "points[0]/x"])
def test_indices_as_ros_users_write_them(text):
    assert FieldPath.parse(text).resolve({"points": [{"x": 1.5}]}) == 1.5


@pytest.mark.parametrize("text", ["a..b", "a.", "a[x]", ".a/"])
def test_malformed_dotted_paths_are_refused(text):
    with pytest.raises(FieldPathError):
        FieldPath.parse(text)


def test_echo_refuses_a_bad_topic_name_with_one_line():
    res = CliRunner().invoke(cli, ["echo", "//robot1"])
    assert res.exit_code == 2 and "'/robot1'" in res.output


# ------------------------------------------------------------------ JSON and times
def test_json_has_no_float_noise_and_loses_nothing_meant():
    noisy = 51.6 + 0.02
    assert repr(noisy) == "51.620000000000005"
    text = jsonsafe.dumps({"t": noisy, "epoch": 1795480671.6, "tiny": 1.25e-9, "third": 1 / 3,
                           "n": [0.1 + 0.2, float("nan")], "i": 3}, nonfinite=lambda _: None)
    assert text == ('{"t": 51.62, "epoch": 1795480671.6, "tiny": 1.25e-09, '
                    '"third": 0.333333333333333, "n": [0.3, null], "i": 3}')


def snapshot(t: float) -> dict:
    return {"time": t, "application": "patrol", "architecture": "alliance",
            "robots": [{"id": "robot1", "state": "busy", "task": "wander", "online": True,
                        "since": t - 2}],
            "tasks": [{"id": "wander", "state": "allocated", "robots": ["robot1"], "since": t - 2}],
            "alarms": [{"kind": "communication_lost", "subject": "robot\x1b[2", "since": t - 1}],
            "transitions": [{"time": t - 2, "kind": "robot", "subject": "robot1", "from": "idle",
                             "to": "busy"}], "ros2": {"domain": 0, "nodes": [], "topics": []},
            "counts": {"samples": 1, "wrong_type": 0, "field_errors": 0}}


def test_supervise_shows_times_from_its_start_and_json_names_its_clocks():
    from mrta_supervisor.live.cli import ChangeLines, relative, with_clocks
    origin = 1795480671.6
    rel = relative(snapshot(origin + 10.0), origin)
    assert rel["time"] == pytest.approx(10.0) and rel["alarms"][0]["since"] == pytest.approx(9.0)
    assert rel["transitions"][0]["time"] == pytest.approx(8.0)
    assert rel["robots"][0]["since"] == pytest.approx(8.0)
    wall = with_clocks(snapshot(origin), sim_time=False)
    assert list(wall)[:3] == ["time", "wall_time", "sim_time"] and wall["sim_time"] is None
    assert with_clocks(snapshot(51.6), sim_time=True)["sim_time"] == 51.6
    out = io.StringIO()
    lines = ChangeLines(Console(file=out, width=40, soft_wrap=True), origin)
    for t in (1.0, 1.25, 2.0):
        lines(snapshot(origin + t))  # the same states: one line
    text = out.getvalue()
    assert text.count("\n") == 1, text
    assert text.startswith("t=    1.0s  robot1:busy/wander  alarms: communication_lost "
                           "robot\\x1b[2"), text


# ------------------------------------------------------------------ logs
def test_log_lines_show_control_characters_escaped():
    formatter = SafeFormatter("%(levelname)s %(name)s: %(message)s")
    record = logging.LogRecord("mrta.x", logging.WARNING, __file__, 1,
                               "dropped a sample on %s", ("robot1/\x1b[2J\x9bfake\nINFO: forged",),
                               None)
    line = formatter.format(record)
    assert line == ("WARNING mrta.x: dropped a sample on robot1/\\x1b[2J\\x9bfake\\x0aINFO: forged")
    try:
        raise ValueError("bad \x1b[31m")
    except ValueError:
        record.exc_info = sys.exc_info()
    text = formatter.format(record)
    assert "\x1b" not in text and "bad \\x1b[31m" in text and "\nTraceback" in text
    assert formatter.format(logging.LogRecord("m", 20, "", 1, "tab\there é", (), None)) \
        == "INFO m: tab\\x09here é"


@pytest.mark.slow
@pytest.mark.multiprocess
def test_setup_logging_installs_the_escaping_formatter():
    code = ("import logging; from mrta_zenoh.cli.common import setup_logging; setup_logging(); "
            "logging.getLogger('mrta.t').warning('key %s', 'a\\x1b[31mb')")
    err = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60).stderr
    assert err.strip() == "WARNING mrta.t: key a\\x1b[31mb", err


def test_json_lines_stay_json():
    json.loads(jsonsafe.dumps({"x": float("inf")}, nonfinite=str))


LATE = """
import os, signal, sys, time
agent = int(sys.argv[1])
def on_int(*_):
    try:
        os.kill(agent, 0)
        alive = "alive"
    except ProcessLookupError:
        alive = "gone"
    time.sleep(6)  # writing out what it holds: longer than the 5 s every other child gets
    print("agent", alive, flush=True)
    sys.exit(0)
signal.signal(signal.SIGINT, on_int)
print("ready", flush=True)
while True:
    time.sleep(0.1)
"""


@pytest.mark.multiprocess
def test_a_child_stopped_later_is_signalled_after_the_others_end_and_given_its_grace():
    """A mission's recorder (issue 51, the newcomer's `--no-plots` run): stopped with the rest
    and killed after 5 s, a recorder behind on a busy machine lost the mission's end. Stopped
    `later`, it takes what the others said last and writes out what it holds."""
    import sys
    group = ProcessGroup()
    agent = group.start([sys.executable, "-c", "import time; print('ready', flush=True); "
                         "time.sleep(600)"], name="agent")
    assert agent.wait_line(lambda line: line == "ready", 60)
    rec = group.start([sys.executable, "-c", LATE, str(agent.proc.pid)], name="record")
    assert rec.wait_line(lambda line: line == "ready", 60)
    group.stop_all(later=[rec], later_grace=60.0)
    assert agent.describe_exit() == "stopped" and rec.describe_exit() == "stopped"
    assert rec.proc.returncode == 0  # ended on its own, not killed after 5 s
    assert rec.wait_line(lambda line: line.startswith("agent "), 5, from_start=True) == "agent gone"
    assert group.failed() == []
