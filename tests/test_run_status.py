"""An honest run status (supervisor/mission/run_watch.py): a process of the run that lost its token
while the run was on — other than an injected crash, or the simulator ending its run — makes
the run disturbed; a recorder that lost its session, or a recording that ends early, makes it
incomplete. Pure parts on the in-process bus and a manual clock; the real processes, stopped
with SIGSTOP, in tests/process/test_run_status_multiprocess.py."""

from __future__ import annotations

import signal
from types import SimpleNamespace

import pytest

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_supervisor.mission.run_watch import (RECORDER, SIMULATOR, RunWatch,
                                               check_simulator_end, crashed_itself, run_status)
from mrta_supervisor.mission.summary import (COMPLETE, DISTURBED, INCOMPLETE, Disturbance, Summary,
                                             run_problem)
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.bus.inproc import InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.errors import MrtaRuntimeError
from mrta_zenoh.keys import CLOCK_SOURCE_TOKEN, RECORDER_TOKEN
from mrta_zenoh.lockstep.protocol import PARTICIPANT
from mrta_zenoh.processes import Child

CRASHED = SimpleNamespace(returncode=-signal.SIGKILL, signalled=set())       # killed itself
KILLED_BY_US = SimpleNamespace(returncode=-signal.SIGKILL, signalled={signal.SIGKILL})
STOPPED = SimpleNamespace(returncode=0, signalled={signal.SIGINT})


class Run:
    """The tokens a mission's processes hold, on one in-process network."""

    def __init__(self):
        self.net = InProcNetwork()
        self.clock = ManualClock(0.0)
        self.watch = RunWatch(InProcBus(self.net), ALLIANCE, self.clock)
        self.tokens: dict[str, list] = {}

    def up(self, process: str, *keys: str) -> None:
        bus = InProcBus(self.net)
        self.tokens[process] = [bus.declare_token(k) for k in keys]

    def down(self, process: str, at: float) -> None:
        self.clock.set(at)
        for t in self.tokens.pop(process):
            t.close()

    def start(self) -> None:
        for r in ("robot1", "robot2"):
            self.up(r, f"{r}/alliance/agent", f"{PARTICIPANT}/{r}")
        self.up(RECORDER, f"{RECORDER_TOKEN}/abc")
        self.up(SIMULATOR, f"{CLOCK_SOURCE_TOKEN}/1234-x0")



def crash_struck(children, crashes):
    """What the mission runner tells the watch for processes of their own."""
    return lambda process: process in crashes and crashed_itself(children.get(process))

def test_a_quiet_run_with_an_injected_crash_is_undisturbed():
    run = Run()
    run.start()
    run.down("robot2", 30.0)                      # the crash the run injected
    run.down(SIMULATOR, 60.0)                     # the simulator ends its run
    run.watch.end()
    run.down("robot1", 60.5)                      # the runner stops the rest
    run.down(RECORDER, 60.5)
    assert run.watch.disturbances(crash_struck({"robot2": CRASHED}, {"robot2"})) == []


def test_a_token_lost_and_back_is_a_disturbance_even_for_a_crash_target():
    run = Run()
    run.start()
    run.down("robot1", 21.3)                      # stopped past the lease …
    run.clock.set(35.0)
    run.up("robot1", "robot1/alliance/agent", f"{PARTICIPANT}/robot1")  # … and resumed
    run.down("robot2", 12.0)
    run.clock.set(14.0)
    run.up("robot2", "robot2/alliance/agent")
    run.down("robot2", 30.0)                      # then its crash
    run.watch.end()
    assert run.watch.disturbances(crash_struck({"robot2": CRASHED}, {"robot2"})) == [
        Disturbance("robot1", 21.3, 35.0), Disturbance("robot2", 12.0, 14.0)]


def test_a_final_loss_is_a_crash_only_if_the_process_killed_itself():
    for child, crashes, expected in ((CRASHED, {"robot2"}, []),
                                     (KILLED_BY_US, {"robot2"}, [Disturbance("robot2", 30.0)]),
                                     (STOPPED, {"robot2"}, [Disturbance("robot2", 30.0)]),
                                     (CRASHED, set(), [Disturbance("robot2", 30.0)])):
        run = Run()
        run.start()
        run.down("robot2", 30.0)
        run.watch.end()
        assert run.watch.disturbances(crash_struck({"robot2": child}, crashes)) == expected


def test_the_recorder_or_the_simulator_losing_its_session_is_seen():
    run = Run()
    run.start()
    run.down(RECORDER, 34.0)
    run.down(SIMULATOR, 40.0)
    run.clock.set(52.0)
    run.up(SIMULATOR, f"{CLOCK_SOURCE_TOKEN}/1234-x0")  # the simulator was stopped: back
    run.watch.end()
    d = run.watch.disturbances(crash_struck({}, set()))
    assert d == [Disturbance(RECORDER, 34.0), Disturbance(SIMULATOR, 40.0, 52.0)]
    assert run_status(d, 60.0, 60.0) == INCOMPLETE  # the recorder's gap is lost for good
    assert run_status(d[1:], 60.0, 60.0) == DISTURBED


def test_what_goes_after_the_end_or_before_it_came_is_not_counted():
    run = Run()
    run.up("robot1", "robot1/alliance/agent")
    run.watch.end()
    run.down("robot1", 70.0)
    assert run.watch.disturbances(crash_struck({}, set())) == []
    run.watch.close()


def test_a_token_seen_going_and_coming_before_the_clock_moved_is_no_disturbance():
    """At start-up, as a session joins, its token may be reported gone and back at once: no
    simulated time passed, the run was not on. A loss at 0 s that lasts, or a blink later
    (a stopped simulator freezes the clock: gone and back at one instant), still counts."""
    run = Run()
    run.start()
    run.down(RECORDER, 0.0)
    run.up(RECORDER, f"{RECORDER_TOKEN}/abc")
    run.down("robot1", 0.0)
    run.clock.set(4.0)
    run.up("robot1", "robot1/alliance/agent")
    run.down(SIMULATOR, 20.0)
    run.up(SIMULATOR, f"{CLOCK_SOURCE_TOKEN}/1234-x0")
    run.watch.end()
    d = run.watch.disturbances(crash_struck({}, set()))
    assert d == [Disturbance("robot1", 0.0, 4.0), Disturbance(SIMULATOR, 20.0, 20.0)]


class _Sim(Child):
    """The simulator's process as it ended: its exit status and the signals the runner sent
    (Child.__init__ would start a process: set what the rest of Child reads)."""

    def __init__(self, returncode: int, signalled: set[int]):
        self.name, self.argv, self.signalled = "sim", ["sim"], signalled
        self.proc = SimpleNamespace(poll=lambda: returncode)
        self.stdout, self.stderr, self._threads = ["done: 60.0 s simulated"], [], []


@pytest.mark.parametrize("rc, signalled, fails", [
    (0, set(), False),                                  # ended at its duration
    (0, {signal.SIGTERM}, False),                       # stopped by the runner, cleanly
    (-signal.SIGTERM, {signal.SIGTERM}, False),         # died of it as it was ending anyway
    (1, {signal.SIGTERM}, True),                        # crashed while stopping
    (-signal.SIGTERM, set(), True),                     # someone else's SIGTERM
    (3, set(), True)])
def test_a_simulator_the_runner_stopped_once_the_work_was_done_ended_normally(
        rc, signalled, fails):
    sim = _Sim(rc, signalled)
    if fails:
        with pytest.raises(MrtaRuntimeError, match="the simulator"):
            check_simulator_end(sim)
    else:
        check_simulator_end(sim)


@pytest.mark.parametrize("recorded_until, status", [(60.0, COMPLETE), (59.2, COMPLETE),
                                                    (58.9, INCOMPLETE), (34.0, INCOMPLETE),
                                                    (None, INCOMPLETE)])
def test_a_recording_that_ends_early_or_holds_nothing_is_incomplete(recorded_until, status):
    assert run_status([], recorded_until, 60.0) == status


def summary(**fields) -> Summary:
    from mrta_supervisor.mission.summary import MessageRates
    return Summary(mission="patrol", application="patrol", architecture="alliance",
                   duration=60.0, speed=0.0, seed=0, wall_seconds=1.0, robots=["robot1"],
                   who_did_what={}, first_full_allocation=None, coverage={},
                   messages=MessageRates(0.0, 0.0, "alliance"), output="out", files=[],
                   **fields)


def test_the_summary_says_why_in_one_line():
    assert run_problem(summary(lockstep_exact=True)) is None
    assert run_problem(summary(run_status=INCOMPLETE, recorded_until=43.1,
                               disturbances=[Disturbance(RECORDER, 34.0)])) == (
        "the recording does not cover the whole mission (it ends at 43.1 s of 60 s; recorder "
        "lost its token at 34 s)")
    assert run_problem(summary(run_status=INCOMPLETE)) == (
        "the recording does not cover the whole mission (it is empty)")
    # a mission whose work was over early ends then, not at its duration
    assert run_problem(summary(run_status=INCOMPLETE, recorded_until=50.2, ended_at=54.7)) == (
        "the recording does not cover the whole mission (it ends at 50.2 s of 54.7 s)")
    assert run_problem(summary(run_status=DISTURBED, lockstep_exact=False,
                               disturbances=[Disturbance("robot1", 21.3, 35.0)])) == (
        "a process of the run was stopped or cut off (robot1 lost its token at 21.3 s, back "
        "at 35 s): the run is not what its seed gives")
    # a file that reaches the end is incomplete for its recorder's lost session, said so;
    # many processes back at once point at the machine (the 20-robot walkthrough at load 50
    # said "it ends at 259.7 s of 258.6 s")
    blinks = [Disturbance(RECORDER, 19.5, 19.6)] + [Disturbance(f"robot{i}", 122.3, 122.4)
                                                    for i in (11, 12, 13)]
    said = run_problem(summary(run_status=INCOMPLETE, recorded_until=259.7, ended_at=258.6,
                               disturbances=blinks))
    assert said.startswith("the recording does not cover the whole mission (the recorder lost "
                           "its session while the run was on: what was published meanwhile "
                           "never reached the file; recorder lost its token at 19.5 s, back at "
                           "19.6 s;"), said
    assert "of 258.6 s" not in said
    assert said.endswith(" — 4 processes lost their tokens and got them back: the machine was "
                         "too busy for the Zenoh lease (3 s); run fewer processes "
                         "(--agents-per-process) or on a quieter machine"), said
    assert "too busy" not in run_problem(summary(run_status=DISTURBED, disturbances=blinks[:2]))
    assert "2 participant(s) given up" in run_problem(summary(lockstep_exact=False,
                                                              lockstep_given_up=2))


class _Ended:
    """A run's mission process that has ended with `returncode` (experiment._collect reads it)."""

    def __init__(self, returncode: int, stdout: list[str]):
        self.returncode, self.stdout = returncode, stdout

    def running(self) -> bool:
        return False

    def wait(self, timeout) -> int:
        return self.returncode


@pytest.mark.parametrize("status, rc, marked, says", [
    (DISTURBED, 0, "inexact", "robot1 lost its token at 21.3 s, back at 35 s"),
    (INCOMPLETE, 1, "failed", "Error: the recording does not cover the whole mission")])
def test_an_experiment_runs_a_disturbed_or_incomplete_run_again_then_marks_it(
        tmp_path, status, rc, marked, says):
    import time

    from mrta_supervisor.experiment import api as experiment
    from mrta_supervisor.mission.summary import write_summary
    out = tmp_path / "run000"
    out.mkdir()
    write_summary(out / "summary.json", summary(
        run_status=status, lockstep_exact=False, recorded_until=60.0 if rc == 0 else 43.1,
        disturbances=[Disturbance("robot1", 21.3, 35.0)] if rc == 0 else
        [Disturbance(RECORDER, 34.0)]))
    child = _Ended(rc, [f"Error: {run_problem(summary(run_status=INCOMPLETE))}"] if rc else [])
    run = experiment.Run(0, 1, "none", ())
    results = experiment.Results(tmp_path / "results.csv", 1)
    again = experiment._collect({0: (run, child, time.monotonic(), out)}, results, set())
    assert again == [run] and results.rows == []  # first time: run again, no row
    again = experiment._collect({0: (run, child, time.monotonic(), out)}, results, {0})
    assert again == [] and results.rows[0]["status"] == marked
    assert says in results.rows[0]["error"]


def test_a_strangers_participant_token_is_reported_apart_and_disturbs_nothing():
    """One token `@mrta/lockstep/participant/evil` coming and going while the run is on made
    the run `disturbed`, and `mrta experiment` dropped it from the statistics."""
    run = Run()
    run.start()
    run.up("evil", f"{PARTICIPANT}/evil")
    run.down("evil", 12.0)
    run.watch.end()
    processes = {"robot1", "robot2"}
    assert run.watch.disturbances(crash_struck({}, set()), processes) == []
    assert run.watch.strangers(processes) == ["evil"]
    assert run.watch.disturbances(crash_struck({}, set())) == [Disturbance("evil", 12.0)]  # all the run's


def test_an_interrupted_run_says_so_and_is_no_error_of_the_demo(capsys):
    """A Ctrl-C'd (or SIGTERMed) demo wrote no summary (issue 51, the newcomer's list): the
    runner now analyses what was recorded and the summary says it was interrupted; the demo
    prints it, then exits 130 after Ctrl-C, 0 after SIGTERM (tests/process/
    test_cli_conventions_mp.py)."""
    from mrta_supervisor.mission.cli import print_summary
    from mrta_supervisor.mission.summary import summary_json
    from mrta_zenoh.cli.common import console
    s = summary(run_status=INCOMPLETE, recorded_until=12.4, interrupted="Ctrl-C")
    assert run_problem(s) == ("the run was interrupted (Ctrl-C): the figures cover it up to "
                              "12.4 s of 60 s")
    print_summary(console(), s, "Patrol mission", "ALLIANCE", [])
    assert "INTERRUPTED: the run was interrupted (Ctrl-C)" in capsys.readouterr().out
    assert b'"interrupted": "Ctrl-C"' in summary_json(s)
    assert b"interrupted" not in summary_json(summary())  # a run that ran to its end: silent
