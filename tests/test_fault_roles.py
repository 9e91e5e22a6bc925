"""Faults that name a robot by role: `@random` drawn from the instance's own numbers (the same
robot for any run seed), `@first` resolved by the agents at its time from the team's
announcements of their first assignments — here on the in-process bus and a manual clock, the
driver's own loop — and read back by the runner from a recording the same way."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_agent.runtime.host import AgentOptions
from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.codec import encode
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import (FAULTS_ENV, Failure, FaultKind, faults_problem, parse_faults,
                                plan_for, plan_from_env)
from mrta_zenoh.fault_roles import Assigned, assigned_key, draw_random, first_assigned
from mrta_zenoh.fault_tally import Cause
from mrta_zenoh.messages import Header, Odometry, PointCloud, Pose2D, Twist
from mrta_supervisor.mission import roles
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write


# ------------------------------------------------------------------ the grammar
def test_roles_parse_as_subjects_and_are_checked_against_the_team():
    f = parse_faults("stall:@first@5,crash:@random@8,loss:0.1")
    assert [(g.robot, g.kind, g.at) for g in f.failures] == [
        ("@first", FaultKind.STALL, 5.0), ("@random", FaultKind.CRASH, 8.0)]
    assert parse_faults("partition:@first@5+3").failures[0].duration == 3.0
    with pytest.raises(ValueError):
        parse_faults("stall:@second@5")
    with pytest.raises(ValueError, match="two faults"):
        parse_faults("stall:@first@5,crash:@first@6")
    # any team will do, if it has a robot for every role no id names
    assert faults_problem(f, ["robot1", "robot2"], 10.0) is None
    assert "1 robot leave 1 for 2 roles" in faults_problem(f, ["robot1"], 10.0)
    assert "leave 0 for 1 role" in faults_problem(parse_faults("robot1@2,stall:@first@3"),
                                                  ["robot1"], 10.0)
    assert "not before the end" in faults_problem(f, ["robot1", "robot2"], 6.0)


# ------------------------------------------------------------------ @first: the rule
def test_first_assigned_is_the_earliest_before_the_time_ties_to_the_lower_id_naturally():
    heard = {"robot10": 0.4, "robot2": 0.4, "robot3": 0.2, "robot1": 5.0}
    assert first_assigned(heard, 5.0) == "robot3"
    assert first_assigned(heard, 5.0, taken={"robot3"}) == "robot2"  # not robot10: natural
    assert first_assigned(heard, 0.2) is None  # strictly before its time
    assert first_assigned({}, 5.0) is None


# ------------------------------------------------------------------ @random: the instance's
def expected_pick(instance: str, free: list[str]) -> str:
    """The draw by its definition: BLAKE2b-64 of "0\\0instance\\0NAME\\0@random" over 2^64."""
    digest = hashlib.blake2b(f"0\0instance\0{instance}\0@random".encode(),
                             digest_size=8).digest()
    return free[int(int.from_bytes(digest, "big") / 2.0 ** 64 * len(free))]


def test_random_is_drawn_from_the_instance_never_the_run_and_skips_named_robots():
    robots = [f"robot{i}" for i in range(1, 21)]
    faults = parse_faults("robot4@2,stall:@random@5,loss:0.2")
    picks = {}
    for name in ("delivery-r20-t20-0", "delivery-r20-t20-1", "delivery-r20-t20-2"):
        drawn = draw_random(faults, robots, name)
        pick = drawn.failures[1].robot
        free = [r for r in robots if r != "robot4"]
        assert pick == expected_pick(name, free)
        assert drawn.spec == f"robot4@2,stall:{pick}@5,loss:0.2"  # every later hop reads an id
        assert drawn.failures[1] == Failure(pick, 5.0, f"stall:{pick}@5", FaultKind.STALL)
        picks[name] = pick
    assert len(set(picks.values())) > 1  # depends on the instance
    with pytest.raises(ValueError, match="every robot already has a fault"):
        draw_random(parse_faults("robot1@2,@random@3"), ["robot1"], "x")


def test_an_agent_refuses_an_undrawn_random_and_takes_first_only_if_no_item_names_it():
    with pytest.raises(ConfigError, match="drawn by the runner"):
        plan_from_env("robot1", 0, environ={FAULTS_ENV: "crash:@random@5"})
    faults = parse_faults("stall:@first@5,robot2@7")
    plan = plan_for(faults, "robot1", 3)
    assert plan.first.robot == "@first" and plan.taken == {"robot2"}
    assert plan_for(faults, "robot2", 3).first is None  # named: never @first
    struck = plan.struck(plan.first)
    assert struck.stalled(5.0) and not struck.stalled(4.9) and struck.first is None


# ------------------------------------------------------------------ @first in the agent's loop
def make(tmp_path, robot: str, spec: str):
    sets = [{"task": "a", "fast": 50.0}]
    rf = write(tmp_path / f"{robot}.yaml", robot_yaml(sets, spin=10.0, broadcast=5.0, tau=1.0))
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"], {"a": []}))
    bus, clock = InProcBus(), ManualClock(0.0)
    agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions(robot, rf, tf)), bus, clock,
                           np.random.default_rng(1))
    agent.faults = plan_for(parse_faults(spec), robot, 0)
    agent.start()
    return agent, bus, clock


def run(agent, bus, clock, until, then=()):
    """The agent's own loop on the manual clock, sensors fed; `then`: (time, callable) done
    once the clock has passed that time."""
    pending = sorted(then)
    for t in agent.schedule(until):
        clock.set(t)
        while pending and pending[0][0] <= t:
            pending.pop(0)[1]()
        robot = agent.robot_id
        bus.publish(keys.odom(robot), Odometry(Header(robot, t, 0), Pose2D(0.0, 0.0, 0.0),
                                               Twist(0.0, 0.0)))
        bus.publish(keys.sonar(robot), PointCloud(Header(robot, t, 0), ()))


@pytest.mark.parametrize("other_at,struck", [(0.05, False), (0.9, True), (None, True)])
def test_the_first_assigned_robot_stalls_at_the_faults_time_and_no_other(tmp_path, other_at,
                                                                         struck):
    """robot1 activates its task within its first ticks and announces it, once; robot2 says
    it was assigned at `other_at` (None: never). At 2 s the earlier of the two is struck."""
    agent, bus, clock = make(tmp_path, "robot1", "stall:@first@2")
    said = []
    bus.subscribe(assigned_key("robot1"), said.append)
    other = [] if other_at is None else [(other_at, lambda: bus.publish(
        assigned_key("robot2"), Assigned(Header("robot2", other_at, 1), "b")))]
    run(agent, bus, clock, 1.9, other)
    assert not agent.stalled and agent.faults.first is not None  # not resolved before its time
    run(agent, bus, clock, 4.0)
    assert agent.stalled is struck and agent.faults.first is None
    assert len(said) == 1 and said[0].message.task_id == "a"
    if struck and other_at is not None:  # it said so before robot2 did
        assert said[0].message.header.stamp < other_at


def test_an_at_first_partition_of_a_teammate_cuts_what_it_sends_in_its_window(tmp_path):
    """robot2 was assigned first: at 2 s the partition strikes it, so robot1 (not cut off)
    drops what robot2 sends from 2 s to 5 s — and hears it before and after."""
    agent, bus, clock = make(tmp_path, "robot1", "partition:@first@2+3")
    heard = []
    hear = agent.coordinator.hear
    agent.coordinator.hear = lambda kind, sender, msg, at: (
        heard.append(msg.header.seq) if sender == "robot2" else None) or hear(kind, sender,
                                                                               msg, at)
    agent._on_token(ALLIANCE.key("robot2", "agent"), True)  # robot2 on the team

    def say(t, seq):
        return (t, lambda: bus.publish(ALLIANCE.key("robot2", "inter_robot_communication"),
                                       InterRobotCommunication(Header("robot2", t, seq), "b",
                                                               60.0)))
    run(agent, bus, clock, 6.0, [(0.01, lambda: bus.publish(
        assigned_key("robot2"), Assigned(Header("robot2", 0.01, 1), "b"))),
        say(1.0, 1), say(2.5, 2), say(4.9, 3), say(5.5, 4)])
    assert not agent.faults.cut_off(3.0) and agent.faults.sender_cut("robot2", 3.0)
    assert heard == [1, 4] and agent.injector.counts[Cause.CUT_OFF] == 2


def test_a_robot_an_item_names_is_never_first_and_announcements_only_come_with_first(tmp_path):
    agent, bus, clock = make(tmp_path, "robot1", "stall:@first@2,crash:robot1@9")
    said = []
    bus.subscribe("*/faults/assigned", said.append)
    run(agent, bus, clock, 3.0)
    assert not agent.stalled and said == []  # robot1 is named: it cannot be @first
    agent, bus, clock = make(tmp_path, "robot1", "loss:0.1")
    said = []
    bus.subscribe("*/faults/assigned", said.append)
    run(agent, bus, clock, 3.0)
    assert said == []  # no role in the run: nothing new on the wire


def test_a_restart_of_time_resolves_first_again(tmp_path):
    agent, bus, clock = make(tmp_path, "robot1", "stall:@first@2")
    run(agent, bus, clock, 3.0)
    assert agent.stalled
    agent.restart(0.0)
    assert not agent.stalled and agent.faults.first is not None


# ------------------------------------------------------------------ the runner's side
def record(robot: str, stamp: float, frame: str | None = None):
    msg = Assigned(Header(frame or robot, stamp, 1), "t1")
    return (assigned_key(robot), "application/msgpack;mrta_msgs/Assigned", 0, encode(msg))


def test_the_runner_reads_whom_first_struck_from_the_recording():
    records = [record("robot3", 0.6), record("robot2", 0.4), record("robot9", 0.4),
               record("robot1", 0.1, frame="robot7")]  # a forged one: its key says robot1
    faults = parse_faults("stall:@first@2")
    assert roles.announcements(records) == {"robot3": 0.6, "robot2": 0.4, "robot9": 0.4}
    assert roles.struck(faults.primary, faults, records).robot == "robot2"
    early = parse_faults("stall:@first@0.3")
    assert roles.struck(early.primary, early, records) is None  # nobody before 0.3 s
    named = parse_faults("robot2@1,stall:@first@2")
    assert roles.struck(named.failures[1], named, records).robot == "robot9"
    assert roles.struck(named.primary, named, records) == named.primary


def test_the_runner_expects_the_crash_of_whichever_robot_first_struck():
    crashes = roles.crash_targets(parse_faults("crash:@first@3,robot4@5"),
                                  {"robot1": False, "robot2": True, "robot4": True})
    assert crashes == {"robot2", "robot4"}
    assert roles.crash_targets(parse_faults("stall:@first@3"), {"robot2": True}) == set()


def test_a_bad_subject_is_told_which_subjects_there_are():
    """A typo'd role gets an error that names the roles a subject may be."""
    with pytest.raises(ValueError, match="@first or @random"):
        parse_faults("crash:@nobody@3")
