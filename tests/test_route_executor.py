"""The route executor (mrta_agent.route.executor) on a manual clock: a route served in its order,
a held head not skipped, a re-plan keeping the task in progress or leaving it, a served task
never served again; and `PluginReadings` answering from a robot's plugins."""

from __future__ import annotations

from dataclasses import dataclass, field

from mrta_agent.runtime.plugins import Plugins
from mrta_agent.route.executor import Change, PluginReadings, RouteExecutor, Served
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist


@dataclass
class Fake:
    """Readings set by the test: which tasks are applicable now, which are finished."""

    blocked: set[str] = field(default_factory=set)
    finished: set[str] = field(default_factory=set)
    cancelled: set[str] = field(default_factory=set)

    def withdrawn(self, task_id: str, now: float) -> bool:
        return task_id in self.cancelled

    def applicable(self, task_id: str, now: float) -> bool:
        return task_id not in self.blocked

    def done(self, task_id: str, now: float) -> bool:
        return task_id in self.finished

    def pose(self):
        return (0.0, 0.0, 0.0)


def test_a_route_is_served_in_its_order_one_task_at_a_time():
    r, world = RouteExecutor(), Fake()
    assert r.assign(["a", "b", "c"], 0.0) == []
    assert r.step(0.0, world) == [Change("set_off", "a", 0.0)]
    assert (r.current, r.since, r.route, r.queue) == ("a", 0.0, ["b", "c"], ["a", "b", "c"])
    assert r.active(0.0, world) == "a"
    assert r.step(1.0, world) == []            # not finished: stays on a
    world.finished.add("a")
    assert r.step(2.0, world) == [Change("served", "a", 2.0), Change("set_off", "b", 2.0)]
    world.finished |= {"b", "c"}
    r.step(3.0, world)
    r.step(4.0, world)
    assert r.served == [Served("a", 2.0), Served("b", 3.0), Served("c", 4.0)]
    assert r.served_ids() == ["a", "b", "c"]
    assert (r.current, r.queue, r.last) == (None, [], "c")
    assert r.active(5.0, world) is None


def test_a_head_whose_evaluator_does_not_hold_is_held_not_skipped():
    r, world = RouteExecutor(), Fake(blocked={"a"})
    r.assign(["a", "b"], 0.0)
    r.step(0.0, world)
    for now in (1.0, 2.0, 3.0):
        r.step(now, world)
        assert r.current == "a" and r.active(now, world) is None  # stands still, keeps a
    assert r.route == ["b"]
    world.blocked.clear()
    assert r.active(4.0, world) == "a"


def test_a_new_route_keeps_the_task_in_progress_at_its_head():
    r, world = RouteExecutor(), Fake()
    r.assign(["a", "b"], 0.0)
    r.step(0.0, world)
    assert r.assign(["c", "a", "b"], 1.0) == []       # a re-plan listing a later
    assert (r.current, r.since, r.queue) == ("a", 0.0, ["a", "c", "b"])


def test_a_new_route_without_the_current_task_leaves_it():
    r, world = RouteExecutor(), Fake()
    r.assign(["a", "b"], 0.0)
    r.step(0.0, world)
    assert r.assign(["b"], 1.0) == [Change("left", "a", 1.0)]
    assert (r.current, r.since, r.last, r.route) == (None, None, "a", ["b"])
    assert r.step(1.0, world) == [Change("set_off", "b", 1.0)]
    assert "a" not in r.served_ids()


def test_a_served_task_is_never_served_again_and_duplicates_collapse():
    r, world = RouteExecutor(), Fake(finished={"a"})
    r.assign(["a"], 0.0)
    r.step(0.0, world)
    r.step(1.0, world)
    assert r.served_ids() == ["a"]
    r.assign(["a", "b", "b", "c"], 2.0)
    assert r.route == ["b", "c"]
    r.step(2.0, world)
    assert r.current == "b"


def test_an_empty_route_stops_the_robot():
    r, world = RouteExecutor(), Fake()
    r.assign(["a"], 0.0)
    r.step(0.0, world)
    assert r.assign([], 1.0) == [Change("left", "a", 1.0)]
    assert r.step(1.0, world) == [] and r.queue == [] and r.active(1.0, world) is None


# ------------------------------------------------------------------ readings from plugins
class Evaluator:
    def __init__(self, ok: bool):
        self.ok = ok

    def is_applicable(self, now: float) -> bool:
        return self.ok


class Layer:
    def __init__(self, finished: bool):
        self.finished = finished

    def done(self, now: float) -> bool:
        return self.finished


class Sensor:
    def __init__(self, latest):
        self.latest = latest


def plugins(**kw) -> Plugins:
    p = Plugins((), (), {}, None)
    p.evaluators.update(kw.get("evaluators", {}))
    p.layers.update(kw.get("layers", {}))
    p.sensors.update(kw.get("sensors", {}))
    return p


def test_plugin_readings_ask_the_evaluator_the_layers_and_the_pose_sensor():
    odom = Odometry(Header("odom", 0.0, 0), Pose2D(1.5, -2.0, 0.25), Twist(0.0, 0.0))
    p = plugins(evaluators={"a": Evaluator(True), "b": Evaluator(False)},
                layers={"a": [Layer(False), Layer(True)], "b": [Layer(False)]},
                sensors={"/odom": Sensor(odom), "/other": Sensor(None)})
    readings = PluginReadings(p, "/odom")
    assert readings.applicable("a", 0.0) and not readings.applicable("b", 0.0)
    assert not readings.applicable("zz", 0.0)          # no evaluator: not applicable
    assert readings.done("a", 0.0) and not readings.done("b", 0.0)
    assert not readings.done("zz", 0.0)
    assert readings.pose() == (1.5, -2.0, 0.25)
    assert PluginReadings(p, "/other").pose() is None   # no message yet
    assert PluginReadings(p, None).pose() is None


def test_a_withdrawn_task_is_left_at_once_and_never_set_off_to_again():
    """A task cancelled at run time (its evaluator's `withdrawn`): left if the robot is on it,
    dropped from the route otherwise, and filtered out of every later route — a held head
    would keep the robot standing by a task nobody may serve."""
    r, world = RouteExecutor(), Fake()
    r.assign(["a", "b", "c"], 0.0)
    r.step(0.0, world)
    world.cancelled |= {"a", "c"}
    assert r.step(1.0, world) == [Change("left", "a", 1.0), Change("set_off", "b", 1.0)]
    assert (r.queue, r.last, r.withdrawn) == (["b"], "a", {"a", "c"})
    assert r.assign(["c", "a", "b", "d"], 2.0) == [] and r.queue == ["b", "d"]
    world.finished.add("b")
    r.step(3.0, world)
    assert r.served_ids() == ["b"] and r.current == "d"
