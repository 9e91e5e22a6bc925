"""A windowed run ends when nothing is left to serve (issue 49 follow-up): under hard windows a
task whose due passed with no service started can never be served, so the run no longer waits
for `--duration` — the supervisor's task watch calls it missed (mission.DeliveryWatch.lapsed,
Supervisor.all_done), the analysis ends the figures there (metrics.done_at) and the printed
summary says what was served and what was missed rather than "every task done". In-process, on
the supervisor's manual clock; one real run: tests/process/test_windows_multiprocess.py."""

from __future__ import annotations

import io
import math
from pathlib import Path
from types import SimpleNamespace

import msgspec
import pytest
from rich.console import Console

from mrta_agent.murdoch.messages import Claim
from mrta_delivery.instance import DeliveryParams, InstanceBody
from mrta_delivery.messages import TaskEvent
from mrta_delivery.metrics import done_at
from mrta_delivery.mission import Delivery, DeliveryWatch
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.state import Supervisor
from mrta_zenoh.codec import encode, encoding_for
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from mrta_zenoh.planning.schedule import window_counts
from mrta_zenoh.tasks.messages import CHANGE, INTAKE, Change

ROBOTS = ("robot1", "robot2", "robot3", "robot4", "robot5")
TESSI = Path(__file__).resolve().parents[1] / "configs" / "applications" / "delivery_tessi"
MISS_SLACK = DeliveryParams().miss_grace  # the default grace: 2 s, as before it was a parameter


def instance(windows: str = "hard") -> InstanceBody:
    """delivery_murdoch's four tasks (its robots are 1 m apart on y = 0, at 0.5 m/s; every task
    at (1, 1)): t1 due at 10 and never started, t2 without a window, t3 due at 20 with 5 s of
    service, t4 due at 30."""
    return msgspec.convert({
        "robots": {r: {"start": [float(k), 0.0], "speed": 0.5} for k, r in enumerate(ROBOTS)},
        "tasks": {"t1": {"position": [1.0, 1.0], "due": 10.0},
                  "t2": {"position": [1.0, 1.0]},
                  "t3": {"position": [1.0, 1.0], "due": 20.0, "service": 5.0},
                  "t4": {"position": [1.0, 1.0], "due": 30.0}},
        "windows": windows}, InstanceBody)


def supervisor(params: InstanceBody, watch: DeliveryWatch | None = None) -> Supervisor:
    app, arch = resolve_application("delivery_murdoch")
    s = Supervisor(arch, app, 0.0, quiet=True, watch=watch or DeliveryWatch(params))
    for r in ROBOTS:
        s.on_liveliness(f"{r}/murdoch/agent", True, 0.0)
    return s


def say(s: Supervisor, robot: str, task: str, kind: str, at: float) -> None:
    s.on_task_sample(f"{robot}/delivery/{kind}", TaskEvent(Header(robot, at, int(at * 10)),
                                                           task, kind), at)


def states(s: Supervisor, now: float) -> dict[str, str]:
    s.update(now)
    return {t["id"]: t["state"] for t in s.snapshot(now)["tasks"]}


def test_a_task_whose_hard_window_passed_unstarted_is_missed_and_the_run_is_over():
    s = supervisor(instance())
    say(s, "robot2", "t2", "started", 5.0)
    say(s, "robot2", "t2", "done", 6.0)
    say(s, "robot3", "t3", "started", 18.0)  # started by its due: being served
    assert states(s, 10.0 + MISS_SLACK - 0.1)["t1"] != "missed"  # the slack for a late word
    assert states(s, 10.0 + MISS_SLACK)["t1"] == "missed"
    assert not s.all_done()
    # t4 held by robot4 past its due is not called missed while it holds it
    for k in range(12):
        at = 25.0 + k * 0.5
        s.on_sample(s.monitors, "robot4/murdoch/claim", "murdoch_msgs/Claim",
                    Claim(Header("robot4", at, k), "t4", 0.0, 2.0), at)
        s.update(at)
    assert states(s, 30.5 + MISS_SLACK)["t4"] == "allocated"
    say(s, "robot3", "t3", "done", 23.0)
    assert states(s, 40.0)["t4"] == "missed"  # robot4's claims ended at 30.5
    assert states(s, 40.0)["t3"] == "done"
    assert s.all_done()  # nothing left to serve: t2, t3 done, t1, t4 missed


def test_a_started_task_its_robot_left_is_missed_once_its_service_would_have_ended():
    s = supervisor(instance())
    say(s, "robot3", "t3", "started", 18.0)
    assert states(s, 18.0 + 5.0 + MISS_SLACK - 0.1)["t3"] != "missed"
    assert states(s, 20.0 + 5.0 + MISS_SLACK)["t3"] == "missed"  # max(due, start) + service


def package_with(tmp_path, value) -> SimpleNamespace:
    """delivery_tessi's package copied as an experiment's run copies it, its layers file's
    `Delivery.miss_grace` overridden as a user would (`--override
    'layers*.Delivery.miss_grace=VALUE'`, or an experiment's `overrides:`): the run as the
    mission hook reads it (its layers file)."""
    from mrta_supervisor.experiment.runs import package_copy
    copy = package_copy(TESSI, tmp_path, (("layers*.Delivery.miss_grace", value),))
    return SimpleNamespace(layers_params=copy / "config" / "layers_tessi_params.yaml")


def test_the_miss_grace_is_the_run_s_delivery_parameter(tmp_path):
    run = package_with(tmp_path, 6.5)
    assert Delivery().task_watch(run).grace == 6.5
    s = supervisor(instance(), DeliveryWatch(instance(), 6.5))
    assert states(s, 10.0 + MISS_SLACK)["t1"] != "missed"  # the default would have said so
    assert states(s, 10.0 + 6.5 - 0.1)["t1"] != "missed"
    assert states(s, 10.0 + 6.5)["t1"] == "missed"
    # the shipped package states the default, so an override has a key to set
    assert "miss_grace: 2.0" in (TESSI / "config" / "layers_tessi_params.yaml").read_text()


@pytest.mark.parametrize("value, what", [(-1.0, "Expected float >= 0.0"),
                                         (61.0, "Expected float <= 60.0"),
                                         ("2 s", "Expected float, got str")])
def test_a_bad_miss_grace_names_the_file_and_key(tmp_path, value, what):
    run = package_with(tmp_path, value)
    with pytest.raises(ConfigError) as e:
        Delivery().task_watch(run)
    text = str(e.value)
    assert "layers_tessi_params.yaml:5: 'Delivery/miss_grace'" in text and what in text


def test_under_soft_windows_nothing_is_ever_missed_and_the_run_waits():
    s = supervisor(instance("soft"))
    for t in ("t2", "t3", "t4"):
        say(s, "robot2", t, "started", 40.0)
        say(s, "robot2", t, "done", 45.0)
    assert states(s, 1000.0)["t1"] != "missed" and not s.all_done()


def cancel(s: Supervisor, task: str, at: float, sender: str = INTAKE) -> None:
    s.on_change(Change(Header(sender, at, 0), "cancel", task), at)  # the intake's tasks/change


@pytest.mark.parametrize("windows", ["hard", "soft"])
def test_a_task_cancelled_at_run_time_is_settled_and_the_run_is_over(windows):
    """Issue 50's `mrta task cancel` of a task nobody will serve now: the run no longer waits
    for it (its due, or for ever without one or under soft windows). A cancel forged in
    another's name settles nothing; one of a task already done leaves it done."""
    s = supervisor(instance(windows))
    for t, at in (("t1", 3.0), ("t3", 8.0), ("t4", 9.0)):
        say(s, "robot2", t, "started", at)
        say(s, "robot2", t, "done", at + 5.0)  # t3 needs its 5 s of service
    cancel(s, "t2", 15.0, sender="someone")  # forged: only the intake's word counts
    assert states(s, 15.0)["t2"] != "cancelled" and not s.all_done()
    cancel(s, "t2", 16.0)  # t2 has no window at all: before, the run ran to --duration
    assert states(s, 16.0)["t2"] == "cancelled" and s.all_done()
    cancel(s, "t1", 17.0)
    assert states(s, 17.0)["t1"] == "done"


def test_a_cancelled_task_is_not_waited_for_nor_missed_in_the_figures():
    params = instance()
    records = [event("robot2", "t2", "started", 5.0), event("robot2", "t2", "done", 6.0),
               event("robot3", "t3", "started", 18.0), event("robot3", "t3", "done", 23.0)]
    assert done_at(records, params) == 30.0  # t1 missed at 10, t4 at 30
    assert done_at(records + [change("t4", 24.0)], params) == 24.0  # over when cancelled
    soft = instance("soft")
    assert done_at(records, soft) is None  # t1, t4 never done: a soft due ends nothing
    assert done_at(records + [change("t1", 7.0), change("t4", 24.0)], soft) == 24.0
    assert done_at(records + [change("t4", 24.0, sender="someone")], soft) is None  # forged
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), (Task("a", (1.0, 0.0), due=5.0),))
    assert window_counts(p, {}, end=9.0).missed == 1
    assert window_counts(p, {}, end=9.0, withdrawn={0}).missed == 0  # cancelled: not missed


def change(task: str, at: float, sender: str = INTAKE) -> tuple:
    return (CHANGE, encoding_for(Change.TYPE_NAME), int(at * 1e9),
            encode(Change(Header(sender, at, 0), "cancel", task)))


def event(robot: str, task: str, kind: str, at: float) -> tuple:
    msg = TaskEvent(Header(robot, at, int(at * 10)), task, kind)
    return (f"{robot}/delivery/{kind}", encoding_for(TaskEvent.TYPE_NAME), int(at * 1e9),
            encode(msg))


def test_the_figures_end_when_nothing_was_left_to_serve():
    """metrics.done_at from the recording, as the live watch decides: each task's first
    completion, or — unserved under hard windows — its due (its service's end if started)."""
    params = instance()
    records = [event("robot2", "t2", "started", 5.0), event("robot2", "t2", "done", 6.0),
               event("robot3", "t3", "started", 18.0), event("robot3", "t3", "done", 23.0)]
    assert done_at(records, params) == 30.0  # t4's due, after t3's completion at 23
    assert done_at(records, params, until=29.0) is None  # t4 not over by the duration
    assert done_at(records[:3], params) == 30.0  # t3 left at 18: over at 20 + 5 < 30
    assert done_at(records, instance("soft")) is None  # a soft due ends nothing


def test_a_missed_task_counts_as_missed_at_a_run_ending_on_its_due():
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), (Task("a", (1.0, 0.0), due=5.0),
                                                 Task("b", (1.0, 0.0))))
    assert window_counts(p, {1: 1.0}, end=5.0).missed == 1
    assert window_counts(p, {1: 1.0}, end=4.9).missed == 0
    assert window_counts(p, {1: 1.0}).missed == 1  # a plan: no end
    b_only = Problem(p.robots, (Task("b", (1.0, 0.0), due=math.inf),))
    assert window_counts(b_only, {}).missed == 0  # no due: never missed


@pytest.mark.parametrize("metrics, words", [
    ({"missed": 0, "completed": 4}, "every task done by 30.0 s"),
    ({"missed": 2, "completed": 2},
     "nothing left to serve — 2 served, 2 missed (hard windows passed) — by 30.0 s")])
def test_the_summary_says_honestly_how_the_work_was_over(metrics, words):
    from mrta_supervisor.mission.cli import print_summary
    from tests.test_summary_sections import summary
    s = summary(duration=300.0, ended_at=30.0, recorded_until=31.0, metrics=metrics)
    out = io.StringIO()
    print_summary(Console(file=out, width=300), s, "Delivery", "MURDOCH", [])
    assert f"31.0 s simulated ({words}, where the figures end; --duration 300)" \
        in out.getvalue()
