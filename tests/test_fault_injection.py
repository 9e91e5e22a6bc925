"""Fault models beyond crash-stop (docs/delivery.md, "Fault grammar"): the grammar, the hop to
the agents through the environment, and the agent driver injecting each fault on a manual
clock — a stall, a partition, seeded loss and latency — for every architecture alike."""

import dataclasses

import numpy as np
import pytest

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_agent.runtime.host import AgentOptions
from mrta_agent.runtime.plugins import Layer
from mrta_supervisor.experiment.api import _failure_problem
from mrta_supervisor.mission.hook import parse_fail
from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import (FAULTS_ENV, SYNTAX, Failure, FaultKind, FaultPlan, Faults,
                                fault_env, faults_problem, parse_faults, plan_for,
                                plan_from_env)
from mrta_zenoh.fault_tally import TALLY_PERIOD, Cause, tally_key
from mrta_zenoh.messages import Header, Odometry, PointCloud, Pose2D, Twist
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write

IRC = "inter_robot_communication"


# ------------------------------------------------------------------ the grammar
def test_every_fault_kind_parses_and_combines():
    f = parse_faults("stall:robot2@30, partition:robot1@5.5+10,loss:0.1,latency:0.2±0.05")
    assert f.failures == (Failure("robot2", 30.0, "stall:robot2@30", "stall"),
                          Failure("robot1", 5.5, "partition:robot1@5.5+10", "partition", 10.0))
    assert (f.loss, f.latency) == (0.1, (0.2, 0.05))
    assert f.primary.robot == "robot2"
    assert parse_faults("latency:0.2+-0.1").latency == (0.2, 0.1)  # ASCII ±
    assert parse_faults("latency:0.2").latency == (0.2, 0.0)
    assert parse_faults("crash:robot2@3").failures == (Failure("robot2", 3.0, "crash:robot2@3"),)
    assert not Faults() and parse_faults("loss:0.5")


@pytest.mark.parametrize("spec,says", [
    ("stal:robot2@30", "did you mean 'stall'"), ("stall:robot2@0", "stall:ROBOT@SECONDS"),
    ("partition:robot2@30", "partition:ROBOT@SECONDS\\+SECONDS"),
    ("partition:robot2@30+0", "seconds > 0"), ("loss:1", "0 < P < 1"), ("loss:0", "0 < P < 1"),
    ("loss:-0.1", "0 < P < 1"), ("latency:0.1±0.2", "jitter at most the mean"),
    ("latency:fast", "latency:MEAN±JITTER"), ("loss:0.1,loss:0.2", "loss given twice"),
    ("robot2@3,stall:robot2@4", "robot2 has two faults"), ("robot2@3,,loss:0.1", "comma"),
    ("", "comma")])
def test_bad_specs_say_what_is_expected_at_every_hop(spec, says):
    with pytest.raises(ValueError, match=says):
        parse_faults(spec)
    if spec:
        assert _failure_problem(spec)  # an experiment's `failures` entry: refused at load
        with pytest.raises(ConfigError, match="--fail"):
            parse_fail(spec)
        with pytest.raises(ConfigError, match=f"\\${FAULTS_ENV}"):
            plan_from_env("robot2", 0, environ={FAULTS_ENV: spec})


def test_robot_faults_are_checked_against_the_run():
    robots = ["robot1", "robot2"]
    assert faults_problem(parse_faults("stall:robot2@30,loss:0.1"), robots, 60) is None
    assert "not one of" in faults_problem(parse_faults("partition:robot9@3+1"), robots, 60)
    assert "not before the end" in faults_problem(parse_faults("stall:robot1@60"), robots, 60)


def test_one_variable_carries_every_kind_and_each_process_takes_its_part():
    spec = "robot1@20,stall:robot2@30,loss:0.25,latency:0.1±0.05"
    faults = parse_faults(spec)
    env = fault_env(faults)
    assert env == {FAULTS_ENV: spec}  # one channel: crashes travel with the rest
    assert fault_env(Faults()) == {}
    assert plan_from_env("robot1", 7, environ=env) == FaultPlan(
        "robot1", 7, None, (), 0.25, (0.1, 0.05), crash_at=20.0)
    assert plan_from_env("robot2", 7, environ=env) == FaultPlan(
        "robot2", 7, 30.0, (), 0.25, (0.1, 0.05))
    assert plan_from_env("robot3", 7, environ=env) == FaultPlan(  # the channel's part only
        "robot3", 7, None, (), 0.25, (0.1, 0.05))
    assert plan_from_env("robot1", 7, environ={}) is None
    # a subject need not be a robot: a process of any name takes its own crash the same way
    assert plan_from_env("dispatcher", 1, environ={FAULTS_ENV: "crash:dispatcher@4"}
                         ).crash_at == 4.0


def test_every_kind_is_written_read_and_carried_the_same_way():
    """What adding a kind takes (docs/architecture.md, "Adding a fault kind"): each kind has its
    syntax; a channel kind a field of Faults named like it and a FaultPlan field."""
    plan_fields = {f.name for f in dataclasses.fields(FaultPlan)}
    for kind in FaultKind:
        syntax = SYNTAX[kind]
        if syntax.subject:
            assert parse_faults(syntax.usage.split("e.g. ")[1]).failures[0].kind is kind
        else:
            example = syntax.usage.split("e.g. ")[1]
            value = getattr(parse_faults(example), kind.value)
            assert value and kind.value in plan_fields
            assert getattr(plan_for(parse_faults(example), "robot1", 0), kind.value) == value
    assert [str(k) for k in FaultKind] == ["crash", "stall", "partition", "loss", "latency",
                                           "range"]


# ------------------------------------------------------------------ seeded channel faults
def test_loss_and_latency_are_seeded_per_message_and_order_free():
    plan = plan_for(parse_faults("loss:0.3,latency:0.2±0.1"), "robot1", 42)
    msgs = [("robot2/alliance/" + IRC, seq) for seq in range(4000)]
    lost = [plan.lost(k, s) for k, s in msgs]
    assert lost == [plan.lost(k, s) for k, s in reversed(msgs)][::-1]  # any order, same draw
    assert lost == [FaultPlan("robot1", 42, loss=0.3).lost(k, s) for k, s in msgs]
    assert 0.26 < sum(lost) / len(lost) < 0.34
    other = [FaultPlan("robot1", 43, loss=0.3).lost(k, s) for k, s in msgs]
    assert other != lost  # another seed, other messages
    delays = [plan.delay(k, s) for k, s in msgs]
    assert min(delays) >= 0.1 and max(delays) <= 0.3 and 0.19 < np.mean(delays) < 0.21


# ------------------------------------------------------------------ the driver injects them
class DriveLayer(Layer):
    def step(self, now, dt):
        self.ctx.publish_cmd(0.3, 0.0)


def make(tmp_path, faults: FaultPlan | None):
    sets = [{"task": "a", "fast": 50.0}]
    rf = write(tmp_path / "r.yaml", robot_yaml(sets, spin=10.0, broadcast=5.0, tau=1.0))
    tf = write(tmp_path / "t.yaml",
               tasks_yaml(["a"], {"a": ["tests.test_fault_injection:DriveLayer"]}))
    bus, clock = InProcBus(), ManualClock(0.0)
    agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions("robot1", rf, tf)), bus, clock,
                           np.random.default_rng(1))
    agent.faults = faults
    agent.start()
    bus.declare_token(ALLIANCE.agent_token("robot2"))
    return agent, bus, clock


def run(agent, bus, clock, until):
    """The agent's own loop (`Agent.schedule`) on the manual clock, sensors fed at each wake-up."""
    loop = agent.schedule(until)
    for t in loop:
        clock.set(t)
        for topic, msg in ((keys.odom("robot1"), Odometry(Header("robot1", t, 0),
                            Pose2D(0.0, 0.0, 0.0), Twist(0.0, 0.0))),
                           (keys.sonar("robot1"), PointCloud(Header("robot1", t, 0), ()))):
            bus.publish(topic, msg)


def spy(agent, what):
    """What the decision logic is handed (`what(message, heard_at)` for each), in order."""
    heard, hear = [], agent.coordinator.hear

    def spying(kind, sender, msg, at):
        heard.append(what(msg, at))
        return hear(kind, sender, msg, at)
    agent.coordinator.hear = spying
    return heard


def recorder(bus, key):
    got = []
    bus.subscribe(key, got.append)
    return got


def test_a_stalled_robot_keeps_broadcasting_but_stops_moving(tmp_path):
    agent, bus, clock = make(tmp_path, FaultPlan("robot1", stall_at=2.0))
    irc = recorder(bus, ALLIANCE.key("robot1", IRC))
    cmds = []
    bus.subscribe("robot1/cmd_vel", lambda s: cmds.append((clock.now(), s.message)))
    run(agent, bus, clock, 6.0)
    assert agent.stalled and agent.coordinator.active_task == "a"  # still says it is on it
    moving = [t for t, m in cmds if m != Twist(0.0, 0.0)]
    assert moving and max(moving) < 2.0  # drove until the stall, never after
    assert cmds[-1][1] == Twist(0.0, 0.0)
    after = [s.message for s in irc if s.message.header.stamp >= 2.0]
    assert len(after) >= 19 and all(m.task_id == "a" for m in after)  # heartbeats go on


def test_a_partitioned_robot_hears_nothing_and_is_heard_by_nobody_then_rejoins(tmp_path):
    """robot1 cut off from 2 s to 4 s: it hears nothing, and what it sends meanwhile is on the
    wire (the recording holds what it said) but every receiver drops it — its plan's peers_cut,
    which plan_for gives every process of the run."""
    agent, bus, clock = make(tmp_path, FaultPlan("robot1", partitions=((2.0, 4.0),)))
    irc = recorder(bus, ALLIANCE.key("robot1", IRC))
    heard = spy(agent, lambda msg, at: at)

    def other(t, seq):
        bus.publish(ALLIANCE.key("robot2", IRC), InterRobotCommunication(
            Header("robot2", t, seq), "b", 60.0))

    run(agent, bus, clock, 1.0)
    other(1.0, 1)
    run(agent, bus, clock, 3.0)
    other(3.0, 2)  # inside the cut: lost
    run(agent, bus, clock, 5.0)
    other(5.0, 3)
    run(agent, bus, clock, 6.0)
    assert heard == [pytest.approx(1.0), pytest.approx(5.0)]
    assert agent.injector.counts[Cause.CUT_OFF] == 1
    stamps = [s.message.header.stamp for s in irc]
    assert [t for t in stamps if 2.0 <= t < 4.0]  # it went on saying what its logic said
    peer = plan_for(parse_faults("partition:robot1@2+2"), "robot2", 0)
    assert [t for t in stamps if peer.sender_cut("robot1", t)] == \
        [t for t in stamps if 2.0 <= t < 4.0]
    assert not peer.cut_off(3.0)  # robot2 itself is not cut off


def test_a_receiver_drops_what_a_partitioned_teammate_sent_in_its_window(tmp_path):
    agent, bus, clock = make(tmp_path, plan_for(parse_faults("partition:robot2@2+2"), "robot1", 0))
    heard = spy(agent, lambda msg, at: msg.header.seq)
    for seq, t in enumerate((1.0, 2.0, 3.9, 4.0), start=1):
        run(agent, bus, clock, t)
        bus.publish(ALLIANCE.key("robot2", IRC),
                    InterRobotCommunication(Header("robot2", t, seq), "b", 60.0))
    run(agent, bus, clock, 5.0)
    assert heard == [1, 4] and agent.injector.counts[Cause.CUT_OFF] == 2


def test_loss_drops_the_messages_the_seed_says(tmp_path):
    plan = FaultPlan("robot1", seed=3, loss=0.5)
    agent, bus, clock = make(tmp_path, plan)
    key = ALLIANCE.key("robot2", IRC)
    heard = spy(agent, lambda msg, at: msg.header.seq)
    for seq in range(1, 41):
        run(agent, bus, clock, seq * 0.1)
        bus.publish(key, InterRobotCommunication(Header("robot2", seq * 0.1, seq), "b", 60.0))
    run(agent, bus, clock, 4.2)
    expected = [s for s in range(1, 41) if not plan.lost(key, s)]
    assert heard == expected and 5 < len(expected) < 35
    assert agent.injector.dropped == 40 - len(expected)


def test_a_robot_tells_what_the_faults_did_to_its_messages(tmp_path):
    """Its tally (mrta_zenoh.fault_tally): cumulative, said when it changed and at most every
    TALLY_PERIOD, and once more as it stops — so the summary can show a loss acted."""
    plan = FaultPlan("robot1", seed=3, loss=0.5, latency=(0.2, 0.0))
    agent, bus, clock = make(tmp_path, plan)
    tallies = []
    bus.subscribe(tally_key("robot1"), lambda s: tallies.append(s.message))
    key = ALLIANCE.key("robot2", IRC)
    for seq in range(1, 41):
        run(agent, bus, clock, seq * 0.1)
        bus.publish(key, InterRobotCommunication(Header("robot2", seq * 0.1, seq), "b", 60.0))
    run(agent, bus, clock, 4.2)
    agent.shutdown()
    lost = sum(plan.lost(key, s) for s in range(1, 41))
    assert 5 < lost < 35
    assert (tallies[-1].lost, tallies[-1].delayed) == (lost, 40 - lost)
    assert tallies[-1].cut_off == tallies[-1].out_of_range == 0
    stamps = [t.header.stamp for t in tallies]
    assert all(b - a >= TALLY_PERIOD - 1e-9 for a, b in zip(stamps, stamps[1:-1]))
    assert [t.lost for t in tallies] == sorted(t.lost for t in tallies)  # cumulative
    assert len(tallies) < 4.2 / TALLY_PERIOD + 2


def test_a_robot_without_message_faults_says_no_tally(tmp_path):
    agent, bus, clock = make(tmp_path, FaultPlan("robot1", stall_at=2.0))
    tallies = []
    bus.subscribe(tally_key("robot1"), tallies.append)
    run(agent, bus, clock, 3.0)
    agent.shutdown()
    assert tallies == []


def test_range_drops_the_messages_of_robots_farther_apart_than_r(tmp_path):
    agent, bus, clock = make(tmp_path, FaultPlan("robot1", range=8.0))
    heard = spy(agent, lambda msg, at: msg.header.seq)

    def truth(robot, x, t):
        bus.publish(keys.ground_truth(robot), Odometry(Header(f"{robot}/ground_truth", t, 0),
                                                        Pose2D(x, 0.0, 0.0), Twist(0.0, 0.0)))
    truth("robot1", 0.0, 0.0)
    for seq, x in enumerate((5.0, 9.0, 7.9, 8.1), start=1):
        t = seq * 0.5
        truth("robot2", x, t)
        run(agent, bus, clock, t)
        bus.publish(ALLIANCE.key("robot2", IRC),
                    InterRobotCommunication(Header("robot2", t, seq), "b", 60.0))
    run(agent, bus, clock, 3.0)
    assert heard == [1, 3]  # 9 m and 8.1 m away: dropped
    assert agent.injector.dropped == 2
    assert parse_faults("range:8").range == 8.0
    with pytest.raises(ValueError, match="range:R"):
        parse_faults("range:0")


def test_latency_delays_each_message_by_its_seeded_draw(tmp_path):
    plan = FaultPlan("robot1", seed=5, latency=(0.5, 0.2))
    agent, bus, clock = make(tmp_path, plan)
    key = ALLIANCE.key("robot2", IRC)
    heard = spy(agent, lambda msg, at: (clock.now(), at, msg.header.seq))
    run(agent, bus, clock, 1.0)
    for seq in (1, 2, 3):
        bus.publish(key, InterRobotCommunication(Header("robot2", 1.0, seq), "b", 60.0))
    run(agent, bus, clock, 3.0)
    assert sorted(seq for _, _, seq in heard) == [1, 2, 3]
    for now, at, seq in heard:
        assert at == pytest.approx(1.0 + plan.delay(key, seq))  # heard at its delivery time
        assert 1.3 - 1e-9 <= at <= 1.7 + 1e-9  # 0.5 ± 0.2 s after it was sent
        assert at <= now < at + 0.1 + 1e-9  # handed over at the first tick after it
    assert [at for _, at, _ in heard] == sorted(at for _, at, _ in heard)
    assert len({round(at, 6) for _, at, _ in heard}) == 3  # jitter: each its own delay


def test_an_experiment_takes_every_fault_and_refuses_bad_ones_at_load(tmp_path):
    from mrta_supervisor.experiment.api import load_experiment
    specs = ["none", "robot2@30", "stall:robot2@30",
             "partition:robot1@10+5,loss:0.1,latency:0.2±0.1"]
    good = tmp_path / "good.yaml"
    good.write_text("application: patrol\nduration: 60\nseeds: [1]\nfailures: ["
                    + ", ".join(f'"{s}"' for s in specs) + "]\n")
    exp = load_experiment(good)
    exp.check_against(["robot1", "robot2", "robot3"])
    assert [r.failure for r in exp.runs()] == specs  # passed on to `--fail` as written
    bad = tmp_path / "bad.yaml"
    bad.write_text('application: patrol\nduration: 60\nseeds: [1]\nfailures: [none, "loss:2"]\n')
    with pytest.raises(ConfigError, match=r"bad.yaml:4.*failures\[1\].*0 < P < 1"):
        load_experiment(bad)
    bad.write_text('application: patrol\nduration: 60\nseeds: [1]\n'
                   'failures: [none, "stall:robot9@30"]\n')
    with pytest.raises(ConfigError, match=r"failures\[1\].*robot9 is not one of"):
        load_experiment(bad).check_against(["robot1", "robot2", "robot3"])


def test_a_fail_spec_may_carry_spaces_around_it():
    """`--fail ' none '` said "expected …; or none" — rejecting none while suggesting it."""
    assert parse_fail(" none ") is None and parse_fail("NONE") is None
    assert parse_fail(" loss:0.2 ").spec == "loss:0.2"


def test_a_crash_strikes_at_the_first_wake_up_at_or_after_its_time(tmp_path, monkeypatch):
    """The driver kills its own process (SIGKILL: no shutdown, no goodbye) at its first wake-up
    at or after the crash time, before that tick says anything."""
    import os
    import signal

    from mrta_zenoh import failure

    class Killed(Exception):
        pass

    killed = []

    def kill(pid, sig):
        killed.append((pid, sig))
        raise Killed

    monkeypatch.setattr(failure.os, "kill", kill)
    monkeypatch.setattr(failure.logging, "shutdown", lambda: None)  # pytest's handlers stay
    agent, bus, clock = make(tmp_path, FaultPlan("robot1", crash_at=1.25))
    irc = recorder(bus, ALLIANCE.key("robot1", IRC))
    with pytest.raises(Killed):
        run(agent, bus, clock, 5.0)
    assert killed == [(os.getpid(), signal.SIGKILL)]
    assert clock.now() == pytest.approx(1.3)  # the first 10 Hz wake-up at or after 1.25
    stamps = [s.message.header.stamp for s in irc]
    assert stamps and max(stamps) < 1.25  # it broadcast until then, and not at its last wake


def test_a_message_a_partition_cuts_is_counted_once_whatever_its_latency(tmp_path):
    plan = plan_for(parse_faults("partition:robot2@2+2,latency:0.2"), "robot1", 0)
    agent, bus, clock = make(tmp_path, plan)
    heard = spy(agent, lambda msg, at: msg.header.seq)
    for seq, t in enumerate((1.0, 3.0), start=1):
        run(agent, bus, clock, t)
        bus.publish(ALLIANCE.key("robot2", IRC),
                    InterRobotCommunication(Header("robot2", t, seq), "b", 60.0))
    run(agent, bus, clock, 4.0)
    assert heard == [1]
    assert (agent.injector.counts[Cause.CUT_OFF], agent.injector.counts[Cause.DELAYED]) == (1, 1)


def test_a_robot_named_by_an_item_still_learns_whom_an_at_first_partition_cut_off():
    plan = plan_for(parse_faults("stall:robot1@5,partition:@first@10+5"), "robot1", 0)
    assert plan.stall_at == 5.0 and plan.first is not None
    assert plan.resolved("robot2").peers_cut == (("robot2", 10.0, 15.0),)
    assert plan_for(parse_faults("stall:robot1@5,crash:@first@10"), "robot1", 0).first is None
