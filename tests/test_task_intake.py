"""The task intake's rules (mrta_zenoh/tasks/intake.py), on a hand-driven wall clock: what enters
a run and when, bounds per submitter, malformed requests refused with their reason and counted,
the delivery application's task type, requests as people write them, and a submitter's place in
a secured fleet."""

import json

import pytest

from mrta_zenoh.architectures import architectures
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from mrta_zenoh.refusal_tally import MALFORMED
from mrta_zenoh.tasks.intake import KIND, RATE, FULL, Intake, Limits, Scheduled
from mrta_zenoh.tasks.messages import Op, Outcome, Request
from tests.harness.helpers import CONFIGS

INSTANCE = CONFIGS / "applications" / "delivery" / "config" / "instance.yaml"


class Wall:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def req(op, task_id="", fields=None, priority=0, who="op", rid="r"):
    return Request(Header(who, 0.0, 0), rid, str(op), task_id,
                   "" if fields is None else json.dumps(fields), priority)


def refuse_odd(task_id, fields):
    if "bad" in fields:
        raise ConfigError("bad: not a field")


def test_a_change_enters_at_the_next_step_boundary_in_arrival_order():
    intake = Intake(refuse_odd, known=["t1"], wall=Wall())
    assert intake.offer("op", req(Op.SUBMIT, "n1", {"x": 1}, 3, rid="a")) is None
    assert intake.offer("op", req(Op.CANCEL, "t1", rid="b")) is None  # an instance task
    assert intake.offer("op", req(Op.REPRIORITIZE, "n1", priority=9, rid="c")) is None
    answers, changes = intake.release(2.5)
    assert [(s, a.request, a.outcome, a.at) for s, a in answers] == [
        ("op", "a", "accepted", 2.5), ("op", "b", "accepted", 2.5), ("op", "c", "accepted", 2.5)]
    assert [(c.op, c.task_id, c.header.stamp, c.priority) for c in changes] == [
        ("submit", "n1", 2.5, 3), ("cancel", "t1", 2.5, 0), ("reprioritize", "n1", 2.5, 9)]
    assert json.loads(changes[0].fields) == {"x": 1}
    assert intake.release(2.6) == ([], [])  # nothing twice
    intake.offer("op", req(Op.CANCEL, "t1", rid="d"))
    intake.offer("op", req(Op.CANCEL, "zz", rid="e"))
    answers, changes = intake.release(2.7)
    assert [a.outcome for _, a in answers] == ["unknown", "unknown"] and changes == []
    assert "cancelled at 2.5" in answers[0][1].reason and answers[1][1].reason == "no such task"


def test_malformed_requests_are_refused_with_their_reason_and_counted():
    intake = Intake(refuse_odd, known=["t1"], wall=Wall())
    bad = [req(Op.SUBMIT, "t1", {}, rid="dup"), req(Op.SUBMIT, "-x", {}, rid="id"),
           req(Op.SUBMIT, "n2", {"bad": 1}, rid="app"), req("fly", "n3", rid="op"),
           Request(Header("op", 0, 0), "json", "submit", "n4", "{oops", 0),
           Request(Header("op", 0, 0), "list-not-obj", "submit", "n5", "[1]", 0),
           Request(Header("op", 0, 0), "big", "submit", "n6", json.dumps({"x": "y" * 5000}), 0)]
    for r in bad:
        intake.offer("op", r)
    answers, changes = intake.release(1.0)
    assert changes == [] and all(a.outcome == Outcome.REFUSED for _, a in answers)
    why = {a.request: a.reason for _, a in answers}
    assert "already has a task 't1'" in why["dup"] and "task id" in why["id"]
    assert why["app"] == "malformed: bad: not a field" and "unknown op 'fly'" in why["op"]
    assert "not JSON" in why["json"] and "not a JSON object" in why["list-not-obj"]
    assert "over 4096 bytes" in why["big"]
    assert intake.refused() == {(KIND, "op", MALFORMED, False): 7}


def test_a_flood_is_counted_and_dropped_not_queued_without_bound():
    wall = Wall()
    intake = Intake(refuse_odd, limits=Limits(rate=10, burst=100, pending=150), wall=wall)
    got = [intake.offer("flood", req(Op.SUBMIT, f"f{i}", {}, rid=str(i))) for i in range(130)]
    assert sum(a is None for a in got) == 100  # its burst, then refused at once
    assert {a.reason.split(":")[0] for a in got if a is not None} == {RATE}
    # another submitter is not held back by the flood's bucket, but by the pending bound
    got = [intake.offer("other", req(Op.SUBMIT, f"o{i}", {}, who="other")) for i in range(80)]
    assert sum(a is None for a in got) == 50 and got[-1].reason.startswith(FULL)
    wall.t = 1.0  # a second later the flood's bucket holds `rate` more
    assert sum(intake.offer("flood", req(Op.SUBMIT, f"g{i}", {})) is None
               for i in range(20)) == 0  # still full: the pending bound holds
    answers, changes = intake.release(0.1)
    assert len(changes) == 150 and len(answers) == 150
    assert sum(intake.offer("flood", req(Op.SUBMIT, f"h{i}", {})) is None for i in range(20)) == 10
    assert intake.refused()[(KIND, "flood", RATE, False)] == 30 + 10


def test_a_burst_of_a_thousand_within_a_second_is_taken_whole():
    wall = Wall()
    intake = Intake(refuse_odd, wall=wall)
    for i in range(1000):
        wall.t = i / 1000
        assert intake.offer("op", req(Op.SUBMIT, f"b{i}", {"i": i}, rid=str(i))) is None
    answers, changes = intake.release(1.0)
    assert len(changes) == 1000 and {a.outcome for _, a in answers} == {"accepted"}
    listed = intake.release(1.1)
    intake.offer("op", req(Op.LIST, rid="l"))
    (_, answer), = intake.release(1.2)[0]
    assert answer.outcome == "listed" and len(json.loads(answer.listing)) == 1000


def test_scheduled_changes_enter_at_their_own_instants():
    intake = Intake(refuse_odd, wall=Wall(),
                    schedule=[Scheduled(3.0, Op.SUBMIT, "s1", {"x": 1}, 2, "op"),
                              Scheduled(1.5, Op.SUBMIT, "s0", {}), Scheduled(4.0, Op.CANCEL, "s1")])
    assert intake.next_scheduled() == 1.5
    assert [c.task_id for c in intake.release(1.0)[1]] == []
    assert [(c.task_id, c.header.stamp) for c in intake.release(3.0)[1]] == [("s0", 1.5),
                                                                         ("s1", 3.0)]
    assert [(c.op, c.header.stamp) for c in intake.release(4.0)[1]] == [("cancel", 4.0)]


def test_the_delivery_task_type_admits_what_an_instance_task_may_be():
    from mrta_delivery.instance import load_document
    from mrta_delivery.instances import KIND as DELIVERY
    doc = load_document(INSTANCE)
    DELIVERY.admit(doc, "n1", {"position": [1.0, 2.0], "service": 3, "capability": "lift"})
    for fields, why in [({"positon": [1, 2]}, "unknown field 'positon'.*did you mean 'position'"),
                        ({"position": "here"}, "Expected `array`"),
                        ({"position": [1, 2], "arrival": 4}, "arrival"),
                        ({"position": [1, 2], "capability": "fly"}, "no robot has capability"),
                        ({"position": [99, 2]}, "outside the")]:
        with pytest.raises(ConfigError, match=why):
            DELIVERY.admit(doc, "n1", fields)
    from mrta_delivery.instance import SubmittedChange
    import msgspec
    replay = msgspec.structs.replace(doc, submitted=msgspec.convert(
        [{"at": 2.0, "op": "submit", "id": "n1", "task": {"position": [1, 2], "service": 3},
          "priority": 4, "submitter": "op"}, {"at": 5.0, "op": "cancel", "id": "n1"}],
        list[SubmittedChange]))
    sched = DELIVERY.schedule(replay)
    assert [(s.at, s.op, s.task_id, s.priority) for s in sched] == [
        (2.0, Op.SUBMIT, "n1", 4), (5.0, Op.CANCEL, "n1", 0)]
    assert list(sched[0].fields["position"]) == [1.0, 2.0] and "arrival" not in sched[0].fields
    assert DELIVERY.digest(replay) == DELIVERY.digest(doc)  # the instance's own, unchanged


def test_requests_as_people_write_them(tmp_path):
    from mrta_zenoh.tasks.requests import requests_from_file, task_fields
    assert task_fields(("position=[1, 2]", "service=4", "capability=lift"), None) == ({
        "position": [1, 2], "service": 4, "capability": "lift"}, None)
    assert task_fields(("service=5",), '{"service": 1, "reward": 2}') == (
        {"service": 5, "reward": 2}, None)
    with pytest.raises(ConfigError, match="expected FIELD=VALUE"):
        task_fields(("service",), None)
    f = tmp_path / "burst.yaml"
    f.write_text("tasks:\n  a: {position: [1, 2], priority: 3}\n  b: {position: [0, 0]}\n")
    got = requests_from_file(f)
    assert [(r.task_id, r.priority, r.fields) for r in got] == [
        ("a", 3, {"position": [1, 2]}), ("b", 0, {"position": [0, 0]})]
    f.write_text("- {id: a, position: [1, 2]}\n- {position: [0, 0]}\n")
    with pytest.raises(ConfigError, match=r"burst.yaml:2: .*needs an `id`"):
        requests_from_file(f)


def test_a_submitter_may_only_send_its_own_requests_in_a_secured_fleet():
    from mrta_zenoh.secure import Identity, _identities, rules_for
    ids = _identities(["robot1"], [], [], False, ["ops"])
    assert Identity("ops", "submitter") in ids and Identity("tasks", "tasks") in ids
    says = ("put", "delete", "declare_queryable", "reply")  # publish, answer queries
    rules = {tuple(r["messages"]): r["key_exprs"] for r in rules_for(Identity("ops", "submitter"))}
    assert rules[says] == ["tasks/request/ops"]
    intake = {tuple(r["messages"]): r["key_exprs"] for r in rules_for(Identity("tasks", "tasks"))}
    assert {"tasks/change", "tasks/answer/*", "tasks/history"} <= set(intake[says])
    robot = {tuple(r["messages"]): r["key_exprs"] for r in rules_for(Identity("robot1", "robot"))}
    assert not any(k.startswith("tasks/") for k in robot[says])  # robots cannot submit


def test_requests_are_taken_while_the_intake_checks_a_step():
    """`release` checks outside the lock `offer` takes (the network's thread): a slow check does
    not hold a receiving thread back (blocked past Zenoh's lease, it would lose its link)."""
    import threading
    started, go = threading.Event(), threading.Event()

    def slow(task_id, fields):
        started.set()
        assert go.wait(10)

    intake = Intake(slow, wall=Wall())
    intake.offer("op", req(Op.SUBMIT, "a", {}))
    worker = threading.Thread(target=intake.release, args=(1.0,))
    worker.start()
    assert started.wait(10)
    assert intake.offer("op", req(Op.SUBMIT, "b", {})) is None  # not blocked by the check
    go.set()
    worker.join(10)
    assert [c.task_id for c in intake.release(1.1)[1]] == ["b"]


def test_a_run_gets_an_intake_only_when_reachable_or_scheduled(tmp_path):
    """Every other run is as before: no intake process, no extra lockstep participant."""
    from types import SimpleNamespace
    from mrta_supervisor.mission.hook import MissionOptions
    from mrta_supervisor.mission.runner import _start_intake

    class Group:
        def __init__(self):
            self.started = []

        def start(self, argv, name):
            self.started.append((name, argv))
            return name

    def run(options, path=INSTANCE, arch="central"):
        return SimpleNamespace(options=options, arch=architectures()[arch],
                               mission=SimpleNamespace(instance_file=lambda _run: path))

    g = Group()
    assert _start_intake(run(MissionOptions()), g, []) is None and g.started == []
    assert _start_intake(run(MissionOptions(), path=None), g, []) is None
    assert _start_intake(run(MissionOptions(rendezvous="tcp/127.0.0.1:1")), g, ["-x"]) == "tasks"
    name, argv = g.started[-1]
    assert "--sim-time" in argv and argv[-1] == "-x"
    assert argv[argv.index("--instance") + 1] == str(INSTANCE)
    scheduled = tmp_path / "replay.yaml"
    scheduled.write_text(INSTANCE.read_text() + "submitted:\n  - {at: 1.5, op: cancel, id: t3}\n")
    assert _start_intake(run(MissionOptions(instance=scheduled)), g, []) == "tasks"
    assert str(scheduled) in g.started[-1][1] and "--closed" not in g.started[-1][1]
    # an architecture growing no task at run time: its intake refuses submissions, saying why
    _start_intake(run(MissionOptions(rendezvous="tcp/127.0.0.1:1"), arch="alliance"), g, [])
    argv = g.started[-1][1]
    assert argv[argv.index("--closed") + 1] == architectures()["alliance"].submitted_refusal()


def test_an_open_rmf_task_request_maps_to_a_point_task():
    """Open-RMF's task_request JSON (delivery: its dropoff; compose: its go_to_place activity;
    its priority), places as "X,Y"; what a simulated run cannot mean is refused with why."""
    from mrta_zenoh.tasks.requests import task_fields
    delivery = {"category": "delivery", "priority": {"type": "binary", "value": 1},
                "description": {"pickup": {"place": "0,0", "handler": "h", "payload": []},
                                "dropoff": {"place": "1.5,-2", "handler": "h", "payload": []}}}
    assert task_fields((), json.dumps(delivery)) == ({"position": [1.5, -2.0]}, 1)
    go = {"category": "compose", "description": {"category": "go_to_place", "phases": [
        {"activity": {"category": "go_to_place", "description": {"waypoint": "3,0.5"}}}]}}
    assert task_fields(("service=2",), json.dumps(go)) == ({"position": [3.0, 0.5],
                                                            "service": 2}, None)
    for bad, why in [({**go, "unix_millis_earliest_start_time": 17e11}, "wall-clock"),
                     ({"category": "patrol", "description": {}}, "category 'patrol'"),
                     ({**delivery, "description": {"dropoff": {"place": "lobby"}}},
                      "no named places")]:
        with pytest.raises(ConfigError, match=why):
            task_fields((), json.dumps(bad))


def test_the_history_a_late_view_asks_for_is_the_task_set_so_far_bounded_by_its_tasks():
    """`tasks/history` (Intake.history): each task that entered, with its priority now, and
    each cancellation, in the order of their instants — a hundred reprioritisations add no
    change to it; and over the in-process bus a late asker gets it (Bus.answer_queries)."""
    from mrta_zenoh.bus import InProcBus, InProcNetwork
    from mrta_zenoh.tasks.messages import HISTORY, Change
    intake = Intake(refuse_odd, known=["t1"], wall=Wall())
    assert intake.history() == []
    intake.offer("op", req(Op.SUBMIT, "n1", {"x": 1}, 1, rid="a"))
    intake.release(1.0)
    intake.offer("op", req(Op.SUBMIT, "n2", {"x": 2}, rid="b"))
    intake.offer("op", req(Op.CANCEL, "t1", rid="c"))
    intake.release(2.0)
    for k in range(100):
        intake.offer("op", req(Op.REPRIORITIZE, "n1", priority=k, rid=f"p{k}"))
    intake.offer("op", req(Op.CANCEL, "n1", rid="d"))
    intake.release(3.0)
    history = intake.history()
    assert [(c.op, c.task_id, c.header.stamp, c.priority) for c in history] == [
        ("submit", "n1", 1.0, 99), ("submit", "n2", 2.0, 0), ("cancel", "t1", 2.0, 0),
        ("cancel", "n1", 3.0, 99)]
    assert json.loads(history[0].fields) == {"x": 1}
    net = InProcNetwork()
    server, late = InProcBus(net), InProcBus(net)
    heard = []
    with server.answer_queries(HISTORY, intake.history):
        assert late.query(HISTORY, heard.append, msg_type=Change, timeout=1.0) == 4
    assert [s.message for s in heard] == history
    assert late.query(HISTORY, heard.append, msg_type=Change, timeout=1.0) == 0  # closed
