"""Tasks submitted at run time are served (issue 50; docs/tasks.md, "How each architecture takes
a new task"), checked over every registered architecture as the conformance suite is: a delivery
team in one process (tests/harness/delivery_team.py: the real plugins, the in-process bus, one
manual clock) serves its instance, a task enters through the intake's `tasks/change` while it
runs, and some robot serves it — or, for an architecture that grows no task at run time, the
run's intake refuses the submission, saying why."""

from __future__ import annotations

import json

import pytest

from mrta_delivery.instances import DeliveryGeneratorParams, generate_document
from mrta_zenoh.architectures import architectures
from mrta_zenoh.messages import Header
from mrta_zenoh.tasks.intake import CLOSED, Intake
from mrta_zenoh.tasks.messages import Op, Outcome, Request
from mrta_agent.ssi.messages import OPEN
from tests.harness.delivery_team import PACKAGE, DeliveryTeam

ARCHS = architectures()
TAKES = sorted(name for name, a in ARCHS.items() if a.takes_submitted)
REFUSES = sorted(name for name, a in ARCHS.items() if not a.takes_submitted)
NEW = {"position": [1.5, -2.0], "service": 1.0}


def team_of(arch: str, tmp_path) -> DeliveryTeam:
    doc = generate_document(DeliveryGeneratorParams(robots=2, tasks=2, capabilities=""), 3)
    return DeliveryTeam(arch, doc, tmp_path / arch)


def served(team: DeliveryTeam, task: str) -> list[tuple[str, float]]:
    return [(robot, at) for robot, t, event, at in team.events if t == task and event == "done"]


def run_until_served(team: DeliveryTeam, task: str, until: float) -> None:
    while team.clock.now() < until and not served(team, task):
        team.step()


@pytest.mark.parametrize("arch", TAKES)
def test_a_task_submitted_while_the_team_works_is_served(arch, tmp_path):
    assert arch in PACKAGE, f"{arch}: add its delivery package to tests/harness/delivery_team.py"
    team = team_of(arch, tmp_path)
    try:
        for _ in range(30):  # 3 s: the team is at work on its instance
            team.step()
        entered = team.submit("n1", NEW)
        run_until_served(team, "n1", entered + 90.0)
        done = served(team, "n1")
        assert len(done) == 1, (arch, done)
        robot, at = done[0]
        assert robot in team.doc.robots and at > entered
        started = [a for r, t, e, a in team.events if t == "n1" and e == "started"]
        assert started and started[0] > entered + 0.1 - 1e-9  # taken the tick after it entered
        until = team.clock.now() + 120.0  # the instance's own tasks are still served
        while not set(team.doc.tasks) <= team.done() and team.clock.now() < until:
            team.step()
        assert set(team.doc.tasks) <= team.done()
    finally:
        team.close()


@pytest.mark.parametrize("arch", TAKES)
def test_a_forged_change_grows_nothing(arch, tmp_path):
    """A `tasks/change` whose header is not the intake's is believed for nothing: no robot
    serves the task, every agent counts it (kind task_change, reason not_intake)."""
    from mrta_zenoh.tasks.messages import CHANGE, Change
    team = team_of(arch, tmp_path)
    try:
        team.step()
        team.world.publish(CHANGE, Change(Header("robot1", team.clock.now(), 1), "submit", "f1",
                                          json.dumps(NEW)))
        for _ in range(200):
            team.step()
        assert not served(team, "f1")
        for name, agent in team.agents.items():
            counts = agent.run_time_tasks.refusals()
            assert counts == {("task_change", "-", "not_intake", True): 1}, name
            assert "f1" not in agent.plugins.evaluators
    finally:
        team.close()


@pytest.mark.parametrize("arch", REFUSES)
def test_an_architecture_growing_no_task_refuses_submissions_clearly(arch):
    why = ARCHS[arch].submitted_refusal()
    assert ARCHS[arch].title in why
    intake = Intake(lambda tid, fields: None, closed=why)
    assert intake.offer("ops", Request(Header("ops", 0.0, 1), "r1", str(Op.SUBMIT), "n1",
                                       json.dumps(NEW))) is None
    answers, changes = intake.release(1.0)
    assert not changes
    (_, answer), = answers
    assert answer.outcome == str(Outcome.REFUSED) and answer.reason == f"{CLOSED}: {why}"
    # a cancellation of the instance's own task is still taken
    intake = Intake(lambda tid, fields: None, known=["t1"], closed=why)
    intake.offer("ops", Request(Header("ops", 0.0, 2), "r2", str(Op.CANCEL), "t1"))
    answers, changes = intake.release(1.0)
    assert [c.task_id for c in changes] == ["t1"]


# --- priority orders something real (docs/tasks.md, "Priority") ---------------------------------

ONE_ROBOT = {"name": "prio", "robots": {"robot1": {"start": [0.0, 0.0], "speed": 0.5}},
             "tasks": {"t1": {"position": [0.0, 1.0], "service": 1.0}}}


def first_of_two(arch: str, tmp_path, urgent: str) -> tuple[list[str], list[str]]:
    """One robot, its own task, then n1 and n2 entering together on either side of it, the
    same distance away, `urgent` with priority 5: (the order they were awarded in, for an
    auction — [] otherwise —, the order they were served in)."""
    import msgspec
    from mrta_delivery.instance import InstanceDoc
    team = DeliveryTeam(arch, msgspec.convert(ONE_ROBOT, InstanceDoc), tmp_path / urgent)
    try:
        team.step()
        for tid, x in (("n1", -2.0), ("n2", 2.0)):
            team.submit(tid, {"position": [x, 1.0], "service": 1.0},
                        priority=5 if tid == urgent else 0)
        while len(team.done() & {"n1", "n2"}) < 2 and team.clock.now() < 120.0:
            team.step()
        logic = getattr(team.agents["robot1"].coordinator, "logic", None)
        awards = [logic.problem.tasks[a.task].id for a in getattr(logic, "awards", ())]
        served_order = [t for _, t, e, _ in sorted(team.events, key=lambda e: e[3])
                        if e == "done" and t in ("n1", "n2")]
        return [t for t in awards if t in ("n1", "n2")], served_order
    finally:
        team.close()


@pytest.mark.parametrize("arch", TAKES)
def test_priority_decides_which_of_two_like_tasks_comes_first(arch, tmp_path):
    """Two tasks alike but for where (mirror images) and their priority: whichever has the
    priority is awarded first (SSI, TeSSI: the auction's order) or served first (central:
    the queue's order; CBBA: its weighed reward outbids the other's for the first place)."""
    for urgent, other in (("n1", "n2"), ("n2", "n1")):
        awarded, served_order = first_of_two(arch, tmp_path, urgent)
        assert sorted(served_order) == ["n1", "n2"], (arch, served_order)
        first = awarded if arch in ("ssi", "tessi") else served_order
        assert first == [urgent, other], (arch, urgent, awarded, served_order)


def test_the_printed_summary_says_when_submitted_tasks_were_left_unserved():
    from mrta_delivery.mission import submitted_lines
    assert submitted_lines({}) == []
    left = submitted_lines({"submitted": 4, "submitted_served": 1, "submitted_assigned": 1,
                            "submitted_waiting": 1, "submitted_cancelled": 1})
    assert left == ["submitted at run time: 4 — 1 served, 1 assigned, 1 waiting, 1 cancelled "
                    "(NOT ALL SERVED: 2 left)"]
    done = submitted_lines({"submitted": 2, "submitted_served": 1, "submitted_cancelled": 1})
    assert done[0].endswith("(every one served or cancelled)")


@pytest.mark.parametrize("arch", TAKES)
def test_a_submitted_task_cancelled_before_it_is_served_is_never_served(arch, tmp_path):
    team = team_of(arch, tmp_path)
    try:
        team.step()
        team.submit("n1", {"position": [5.0, 3.5], "service": 1.0})  # far: not served at once
        for _ in range(10):
            team.step()
        team.submit("n1", {}, op="cancel")
        for _ in range(300):
            team.step()
        assert not served(team, "n1")
        for name, agent in team.agents.items():  # every robot grew it, then withdrew it
            if name in team.doc.robots:
                assert agent.plugins.evaluators["n1"].withdrawn(team.clock.now()), name
        if arch == "central":  # the dispatcher plans it no more
            assert "n1" in team.agents["dispatcher"].coordinator.closed
    finally:
        team.close()


def test_a_problem_grown_by_submitted_tasks_is_the_whole_problem_of_the_grown_instance():
    """Problem.grown computes only the new rows and columns (around the walls); they are what
    the instance kind computes for the grown document whole, the old indices unchanged."""
    import msgspec
    from mrta_delivery.instance import InstanceDoc
    from mrta_delivery.instances import KIND
    doc = msgspec.convert({"robots": {"r1": {"start": [-4.0, -2.0], "speed": 0.5},
                                      "r2": {"start": [4.0, 2.0], "speed": 0.7}},
                           "tasks": {"t1": {"position": [-2.0, 2.0]}},
                           "world": {"size": [12.0, 8.0], "walls": [[0.0, -3.0, 0.0, 3.0]]}},
                          InstanceDoc)
    before = KIND.problem(doc)
    grown = KIND.grow(doc, "n1", {"position": [3.0, -2.0], "service": 2.0}, 4.2)
    grown = KIND.grow(grown, "n2", {"position": [-3.0, 3.0]}, 4.2)
    assert grown.tasks["n1"].arrival == 4.2 and list(grown.tasks) == ["t1", "n1", "n2"]
    incremental, whole = KIND.grown_problem(grown, before), KIND.problem(grown)
    assert incremental.tasks == whole.tasks
    assert [t.id for t in incremental.tasks[:1]] == ["t1"]
    for row, expected in zip(incremental.distance, whole.distance):
        assert row == pytest.approx(expected, abs=1e-9)
    assert incremental.distance[0][3] > 7.0 + 0.1  # around the wall's end, not through it


def test_an_ssi_robot_puts_an_urgent_task_before_its_less_urgent_ones_not_where_it_adds_least():
    """SSI's priority band (mrta_agent.ssi.auction, "Priority"): the end of a long path is
    where an urgent task near its end adds least, but it goes — and is bid — before every less
    urgent task; one of priority 1 goes between the priority-2 and the priority-0 ones. With
    no priority given, the place is MinSum's, anywhere."""
    from mrta_agent.ssi.auction import Ssi
    from mrta_zenoh.planning import Problem, Robot, Task
    line = tuple(Task(f"t{k}", (float(k), 0.0)) for k in range(1, 6))  # t5 at x = 5
    p = Problem((Robot("r1", (0.0, 0.0), 1.0),), line)
    ssi = Ssi(p, "r1")
    ssi.path = [0, 1, 2]  # t1 t2 t3; t4, t5 further along the line
    assert ssi.insertion(4) == (pytest.approx(2.0), 3)  # MinSum: at the end
    ssi.task_priority("t5", 2, 0.0)
    cost, place = ssi.insertion(4)
    assert place == 0 and cost == pytest.approx(8.0)  # 0 → 5 → 1: 5 + 4 − 1
    ssi.path = [4, 0, 1, 2]
    ssi.task_priority("t4", 1, 0.0)
    assert ssi.insertion(3)[1] == 1  # after t5 (2), before t1 (0)
    ssi.task_priority("t5", 0, 0.0)
    ssi.task_priority("t4", 0, 0.0)
    assert ssi.places(3) is None  # no priority left: anywhere


@pytest.mark.parametrize("before", [20, 0], ids=["after-setting-off", "before-the-first-award"])
def test_a_settled_ssi_robot_queues_an_award_while_later_rounds_go_on(tmp_path, before):
    """An SSI robot takes each award as it comes once it has set off (mrta_agent.ssi.agent) —
    or once tasks entered at run time, even before the instance's first allocation is over: a
    submitted task is in its executor's queue while some of the same burst is still open in the
    auction — waiting for the last round kept a burst of 200 from being served at all (issue
    50: each round awards one task)."""
    doc = generate_document(DeliveryGeneratorParams(robots=2, tasks=1, capabilities=""), 3)
    team = DeliveryTeam("ssi", doc, tmp_path / "ssi")
    try:
        for _ in range(before):  # 2 s: the instance's task awarded — set off; or at once
            team.step()
        for k in range(12):  # urgent: awarded before the instance's own, which stays open
            team.submit(f"n{k}", {"position": [-4.0 + k * 0.7, 2.0], "service": 1.0}, 1)
        coordinators = [team.agents[r].coordinator for r in doc.robots]
        queued = still_open = False
        while not queued and team.clock.now() < 10.0:
            team.step()
            queued = any(t.startswith("n") for c in coordinators for t in c.route.queue)
            still_open = any(w == OPEN for w in coordinators[0].logic.owners)
        assert queued and still_open, coordinators[0].logic.owners
    finally:
        team.close()
