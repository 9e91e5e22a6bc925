"""A delivery robot drives the path its cost model prices: around a wall between its start and
its task, in the simulator stepped in-process (tests/harness/layer_harness.py), never closer to the wall
than its margin, reaching the task in about the path's length over its speed — and the wall
is a real one: the straight line crosses it."""

from __future__ import annotations

import math

import pytest

from mrta_delivery.generate import world_yaml
from mrta_delivery.instance import DeliveryParams, InstanceBody, RobotSpec, TaskSpec, WorldSpec
from mrta_delivery.keys import event_key
from mrta_delivery.layers import Deliver
from mrta_delivery.messages import TaskEvent
from mrta_simulator.engine import Simulation
from mrta_simulator.robot_model import RobotModel
from mrta_simulator.world import Pose, load_world
from mrta_zenoh.bus.inproc import InProcBus
from mrta_zenoh.planning.geometry import ROBOT_RADIUS, segment_distance
from tests.harness.layer_harness import LayerRun

WALL = (0.0, -2.5, 0.0, 1.5)   # between the start and the task, open above
PARAMS = InstanceBody(
    robots={"robot1": RobotSpec((-3.0, 0.0), 0.6)},
    tasks={"t1": TaskSpec((3.0, 0.0), service=1.0)},
    world=WorldSpec((12.0, 8.0), (WALL,)))


def point_wall(p) -> float:
    x1, y1, x2, y2 = WALL
    t = max(0.0, min(1.0, ((p[0] - x1) * (x2 - x1) + (p[1] - y1) * (y2 - y1))
                     / ((x2 - x1) ** 2 + (y2 - y1) ** 2)))
    return math.hypot(p[0] - x1 - t * (x2 - x1), p[1] - y1 - t * (y2 - y1))


def test_a_robot_drives_around_a_wall_to_a_task_behind_it(tmp_path, monkeypatch):
    import tests.harness.layer_harness as harness
    monkeypatch.setattr(harness, "typed_sections",
                        lambda *classes: {("Delivery", DeliveryParams): DeliveryParams()})
    assert RobotModel().radius == pytest.approx(ROBOT_RADIUS)  # the margin is for this robot
    assert segment_distance((-3.0, 0.0, 3.0, 0.0), WALL) == 0.0  # straight ahead: blocked
    world_file = tmp_path / "world.yaml"
    world_file.write_bytes(world_yaml(PARAMS))
    sim = Simulation(load_world(world_file), {"robot1": Pose(-3.0, 0.0, 0.0)}, seed=1)
    run = LayerRun(sim, "robot1", Deliver, task_id="t1", instance=PARAMS)
    heard, closest = [], [math.inf]
    InProcBus(run.net).subscribe("*/delivery/*", lambda s: heard.append(
        (s.key, round(s.message.header.stamp, 2))), msg_type=TaskEvent)

    def watch(r: LayerRun) -> None:
        closest[0] = min(closest[0], point_wall(r.sim.pose[0][:2]))

    run.run(45.0, each=watch)
    assert [k for k, _ in heard] == [event_key("robot1", "started"), event_key("robot1", "done")]
    x, y = sim.pose[0][0], sim.pose[0][1]
    assert math.hypot(x - 3.0, y) < 0.6
    # the path: up past the wall's top end and down again
    cost = PARAMS.problem().travel(0, None, 0)
    straight = 6.0 / 0.6
    assert cost > straight + 1.0
    started = heard[0][1]
    assert cost < started < cost + 8.0  # + the turns at the start and at each corner, braking
    # the robot's body never touched the wall (its centre kept the radius and most of the margin)
    assert closest[0] > ROBOT_RADIUS + 0.05
    run.close()
