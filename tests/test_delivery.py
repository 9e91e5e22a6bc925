"""The delivery application's plugins on virtual time (in-process bus, manual clock, the
simulator stepped in-process) and its generated packages."""

from __future__ import annotations

import math

import msgspec
import numpy as np
import pytest

from mrta_agent.runtime.builtin import OdometrySensor
from mrta_agent.runtime.params import SensorParams
from mrta_agent.runtime.plugins import AgentContext
from mrta_delivery.evaluators import TaskOpen
from mrta_delivery.generate import INSTANCE, all_files, load_instance
from mrta_delivery.instance import DeliveryParams
from mrta_delivery.keys import event_key
from mrta_delivery.layers import Deliver
from mrta_delivery.messages import TaskEvent
from mrta_delivery.metrics import Entry, measure
from mrta_simulator.engine import Simulation
from mrta_simulator.world import Pose, load_world
from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_zenoh.planning.assignment import ia_costs
from tests.harness.helpers import CONFIGS
from tests.harness.layer_harness import LayerRun

PKG = CONFIGS / "applications" / "delivery"
PARAMS = load_instance()


def context(robot: str, net: InProcNetwork, clock: ManualClock, odom: OdometrySensor):
    return AgentContext(robot, InProcBus(net), clock, np.random.default_rng(0), {"odom": odom},
                        instance=PARAMS)


def evaluator(task: str, robot: str, net, clock):
    odom = OdometrySensor(SensorParams("mrta/odometry", "odom", 2.0, 2.0))
    ev = TaskOpen(task, [odom])
    ev.setup(context(robot, net, clock, odom))
    return ev, odom


def done(bus, robot, task, frame=None, t=1.0, event="done"):
    bus.publish(event_key(robot, event), TaskEvent(Header(frame or robot, t, 1), task, event))


def served(bus, robot, task, t):
    """What a robot that served `task` says: `started` at `t`, `done` a service later."""
    done(bus, robot, task, t=t, event="started")
    done(bus, robot, task, t=t + PARAMS.tasks[task].service)


def test_task_open_follows_arrival_capability_completion_and_sensors():
    net, clock = InProcNetwork(), ManualClock(0.0)
    params = load_instance()
    params.tasks["t2"].arrival = 5.0  # an online task
    ev, odom = evaluator("t2", "robot2", net, clock)
    ev.ctx.instance = params
    ev.setup(ev.ctx)
    assert not ev.is_applicable(0.0)          # not arrived yet
    clock.set(5.0)
    assert ev.is_applicable(5.0)              # arrived; odometry not reported yet: no veto
    odom.on_message(Odometry(Header("robot2", 5.0, 1), Pose2D(0, 0, 0), Twist(0, 0)), 5.0)
    assert ev.is_applicable(6.0)
    assert not ev.is_applicable(7.5)          # odometry reported, then went silent
    odom.on_message(Odometry(Header("robot2", 7.5, 2), Pose2D(0, 0, 0), Twist(0, 0)), 7.5)
    other = InProcBus(net)
    done(other, "robot4", "t2", frame="robot3")  # on robot4's key claiming robot3: dropped
    assert ev.is_applicable(7.5) and ev.board.rejected == 1
    served(other, "robot4", "t2", 14.0)  # robot4 reaches t2 (8.1 m at 0.6 m/s) at 13.4 s
    at = 14.0 + PARAMS.tasks["t2"].service
    odom.on_message(Odometry(Header("robot2", at, 3), Pose2D(0, 0, 0), Twist(0, 0)), at)
    # a teammate delivered it: from the tick after its `done`'s instant, in every layout
    assert ev.is_applicable(at) and not ev.is_applicable(at + 0.1)
    # capabilities: robot2 has no lift, so t1 is never applicable to it
    ev1, _ = evaluator("t1", "robot2", net, clock)
    assert not ev1.is_applicable(1.0)


def test_a_done_from_a_robot_that_never_moved_is_not_believed():
    """Issue 51: four `done` from a robot that never moved ended the run at 3.3 s, 0/4
    delivered. A teammate's `done` counts only after its own `started` a service before, at a
    time it could have reached the task; a `done` on the robot's own key it never said is not
    believed either. Each refusal is in the robot's refusal tally, forged."""
    net, clock = InProcNetwork(), ManualClock(3.0)
    ev, _ = evaluator("t4", "robot1", net, clock)
    forger = InProcBus(net)
    for task in ("t1", "t2", "t3", "t4"):
        done(forger, "robot2", task, t=3.3)
    done(forger, "robot1", "t4", t=3.3)                # on robot1's own key
    done(forger, "robot3", "t4", t=3.0, event="started")  # 5.0 m at 0.4 m/s: 12.6 s at best
    done(forger, "robot3", "t4", t=6.0)
    assert ev.is_applicable(3.3) and not ev.board.done
    (source,) = ev.ctx.refusal_sources
    assert source() == {("task_event", "robot2", "done_not_started", True): 4,
                        ("task_event", "robot1", "own_done_not_said", True): 1,
                        ("task_event", "robot3", "started_too_early", True): 1,
                        ("task_event", "robot3", "done_not_started", True): 1}
    # a `done` heard before its `started` (another key) counts once the `started` comes
    done(forger, "robot4", "t4", t=12.0)
    assert ev.is_applicable(12.0)
    done(forger, "robot4", "t4", t=9.0, event="started")  # 5.4 m at 0.6 m/s: 9.0 s at best
    assert not ev.is_applicable(12.1) and ev.board.done["t4"] == ("robot4", 12.0)
    assert ("task_event", "robot4", "done_not_started", True) not in source()


def test_a_robot_that_delivered_serves_another_task_up_to_the_instances_cap():
    """Time-extended assignment: a robot that delivered serves another task; an instance's
    max_tasks_per_robot caps how many (1: instantaneous assignment)."""
    net, clock = InProcNetwork(), ManualClock(1.0)
    ev, _ = evaluator("t4", "robot1", net, clock)
    assert ev.is_applicable(1.0)
    ev.board.mark_done("t1", "robot1", 1.0)   # its own layer delivered t1
    assert ev.is_applicable(1.0)              # unlimited by default
    for cap, applicable in ((1, False), (2, True)):
        capped = msgspec.structs.replace(load_instance(), max_tasks_per_robot=cap)
        ev.ctx.instance = capped
        ev.setup(ev.ctx)
        assert ev.is_applicable(1.0) is applicable, cap


def test_deliver_drives_to_its_task_serves_it_and_tells_the_team(monkeypatch):
    import tests.harness.layer_harness as harness
    monkeypatch.setattr(harness, "typed_sections",
                        lambda *classes: {("Delivery", DeliveryParams): DeliveryParams()})
    world = load_world(PKG / "worlds" / "delivery.yaml")
    sim = Simulation(world, {"robot2": Pose(-5.0, -1.5, 0.0)}, seed=1)
    run = LayerRun(sim, "robot2", Deliver, task_id="t4", instance=PARAMS)
    heard = []
    InProcBus(run.net).subscribe("*/delivery/*", lambda s: heard.append(
        (s.key, s.message.event, round(s.message.header.stamp, 2))), msg_type=TaskEvent)
    run.run(20.0)
    keys = [h[0] for h in heard]
    assert keys == [event_key("robot2", "started"), event_key("robot2", "done")]
    started, finished = heard[0][2], heard[1][2]
    cost = math.hypot(5.0, 1.0) / 0.7          # the cost model: straight line / speed
    assert cost < started < cost + 3.0         # + acceleration, the initial turn, braking
    assert finished == pytest.approx(started + PARAMS.task("t4").service, abs=0.11)
    x, y = sim.pose[0][0], sim.pose[0][1]
    assert math.hypot(x - 0.0, y + 0.5) < 0.6
    assert run.layer.board.is_done("t4", finished)
    run.close()


def test_the_loader_tells_each_layer_its_task_and_a_layer_without_one_is_refused():
    net, clock = InProcNetwork(), ManualClock(0.0)
    odom = OdometrySensor(SensorParams("mrta/odometry", "odom", 2.0, 2.0))
    with pytest.raises(ConfigError, match="does not know its task"):
        Deliver().setup(context("robot1", net, clock, odom))
    stray = Deliver()
    stray.task_id = "t9"
    with pytest.raises(ConfigError, match="no task 't9'"):
        stray.setup(context("robot1", net, clock, odom))


def test_metrics_count_the_first_assignment_and_handovers():
    inst = PARAMS.problem()
    log = [Entry("t1", "robot3", 1.0, 5.0), Entry("t1", "robot1", 6.0, 20.0, 15.0, 19.0),
           Entry("t2", "robot2", 1.0, 12.0, 10.0, 13.0), Entry("t3", "robot4", 1.0, 14.0, 9.0, 14.0),
           Entry("t4", "robot5", 1.0, 15.0, 12.0, 15.0)]
    for e, reached in zip(log[1:], (15.0, 10.0, 9.0, 12.0)):
        e.reached_at = reached
    m = measure(inst, log, {"robot1": 3.0, "robot2": 4.0})
    cost = ia_costs(inst)
    achieved = cost[2, 0] + cost[1, 1] + cost[3, 2] + cost[4, 3]  # t1's first holder: robot3
    assert m["achieved_cost"] == pytest.approx(achieved, abs=1e-3)
    assert m["ia_optimality"] == pytest.approx(m["optimal_cost"] / achieved, abs=1e-4)
    assert 0 < m["ia_optimality"] <= 1
    assert (m["completed"], m["handovers"], m["makespan"], m["total_distance"]) == (4, 1, 19.0, 7.0)
    assert m["mean_waiting_time"] == pytest.approx((15 + 10 + 9 + 12) / 4)
    assert m["overlaps"] == 0  # robot3 gave t1 up (5.0) before robot1 took it (6.0)
    partial = measure(inst, log[:2], {})
    assert partial["ia_optimality"] is None and partial["makespan"] is None


def test_the_shipped_packages_are_what_the_generator_writes():
    files = all_files(load_instance(INSTANCE))
    assert "delivery/worlds/delivery.yaml" in files
    assert {"delivery_central/config/instance.yaml", "delivery_central_answers.yaml"} <= set(files)
    for rel, data in files.items():
        assert (CONFIGS / "applications" / rel).read_bytes() == data, rel


def test_the_agent_loader_gives_each_delivery_layer_its_task():
    """One registered class (`delivery/deliver`) serves every task: the runtime's loader sets
    `task_id` on the layers it builds for each task, as it gives evaluators theirs."""
    from mrta_agent.alliance.architecture import ALLIANCE
    from mrta_agent.runtime.host import AgentOptions
    config = PKG / "config"
    prepared = ALLIANCE.prepare(AgentOptions("robot1", config / "robot1_alliance_params.yaml",
                                             config / "tasks_alliance_params.yaml",
                                             config / "layers_alliance_params.yaml"))
    layers = prepared.plugins.layers
    assert layers and all(type(layer) is Deliver and layer.task_id == task
                          for task, ls in layers.items() for layer in ls)
    assert sorted(layers) == ["t1", "t2", "t4"]  # robot1 lacks t3's capability


def test_a_bare_demo_runs_the_default_mission_among_several():
    from mrta_supervisor.mission.hook import default_application, missions
    assert {"patrol", "delivery"} <= set(missions())
    assert default_application() == "patrol"  # Patrol.default; delivery is asked for by name


def test_a_task_cancelled_at_run_time_is_inapplicable_and_withdrawn_from_the_next_tick():
    """The intake's cancellation (mrta_zenoh.tasks, `tasks/change`) counts from the tick after
    its instant, the same for every robot (board.py: in lockstep one ticking at that very
    instant may not have received it yet); a change on the key from anyone but the intake, or
    another op, says nothing."""
    from mrta_zenoh.tasks.messages import CHANGE, Change
    net, clock = InProcNetwork(), ManualClock(0.0)
    ev, _ = evaluator("t4", "robot2", net, clock)
    other = InProcBus(net)
    other.publish(CHANGE, Change(Header("someone", 2.0, 0), "cancel", "t4"))
    other.publish(CHANGE, Change(Header("tasks", 2.0, 0), "reprioritize", "t4", priority=3))
    assert ev.is_applicable(3.0) and not ev.withdrawn(3.0)
    other.publish(CHANGE, Change(Header("tasks", 2.0, 0), "cancel", "t4"))
    assert ev.is_applicable(2.0) and not ev.withdrawn(2.0)   # at its instant: not yet
    assert not ev.is_applicable(2.1) and ev.withdrawn(2.1)   # from the next tick on
    ev2, _ = evaluator("t2", "robot2", net, clock)
    assert ev2.is_applicable(2.1)                            # only that task
