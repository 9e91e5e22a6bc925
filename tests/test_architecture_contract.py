"""The architecture contract (mrta_zenoh.architectures) and the fixed driver that runs every
architecture's logic (mrta_agent.runtime.loop.Agent).

A third architecture that lives only in tests/data/plugins (`fixed`: fixed assignment with a
standby, registered by the dist-info beside it) proves the contract is enough: the driver runs
it on the in-process bus, and `mrta demo --architecture fixed` runs the patrol mission with it.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication, Motivation
from mrta_agent.murdoch.architecture import MURDOCH
from mrta_agent.murdoch.messages import Claim, Release
from mrta_agent.runtime import tokens
from mrta_agent.runtime.host import AgentOptions
from mrta_agent.runtime.plugins import load_plugin
from mrta_supervisor.mission.hook import MissionOptions, resolve
from mrta_zenoh import architectures, messages
from mrta_zenoh.architectures import Doing, architecture, architectures as registered
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from tests.harness.helpers import ROOT

PLUGINS = ROOT / "tests" / "data" / "plugins"
PATROL_FIXED = PLUGINS / "patrol_fixed" / "config"


@pytest.fixture
def fixed(monkeypatch):
    """The test architecture registered for this test only (its dist-info on sys.path); its
    module and message type are forgotten afterwards, so no other test sees them."""
    monkeypatch.syspath_prepend(str(PLUGINS))
    monkeypatch.setattr(architectures, "_loaded", {})
    monkeypatch.setattr(messages, "_REGISTRY", dict(messages._REGISTRY))
    yield architecture("fixed")
    for name in [m for m in sys.modules if m.split(".")[0] in ("fixed_arch", "patrol_fixed")]:
        del sys.modules[name]


def test_both_architectures_are_registered_and_unknown_names_are_bad_input():
    assert {"alliance", "murdoch"} <= set(registered())
    assert registered()["alliance"] is ALLIANCE and registered()["murdoch"] is MURDOCH
    with pytest.raises(ConfigError, match="did you mean 'murdoch'"):
        architecture("murdock")


def test_keys_tokens_and_namespace_come_from_the_contract():
    assert ALLIANCE.agent_token("robot1") == "robot1/alliance/agent"
    assert ALLIANCE.agent_tokens == "*/alliance/agent"
    assert ALLIANCE.every("motivation") == "*/alliance/motivation/**"
    assert MURDOCH.every("claim") == "*/murdoch/claim"
    assert MURDOCH.is_coordination_key("robot2/murdoch/bid")
    assert not MURDOCH.is_coordination_key("robot2/alliance/motivation/a")
    assert not hasattr(architectures.Architecture, "failure_env")  # faults: the framework's


def test_coordination_is_what_robots_tell_each_other_sub_keys_included():
    """ALLIANCE's coordination is its broadcast alone (Motivation and SensoryFeedback are
    monitoring); MURDOCH's is every kind it sends, on sub-keys too (announcement/<task>)."""
    assert ALLIANCE.coordination == ("inter_robot_communication",)
    assert set(MURDOCH.coordination) == set(MURDOCH.messages)
    assert ALLIANCE.is_coordination_key("robot1/alliance/inter_robot_communication")
    assert not ALLIANCE.is_coordination_key("robot1/alliance/motivation/wander")
    assert not ALLIANCE.is_coordination_key("robot1/alliance/sensory_feedback/wander")
    assert ALLIANCE.is_namespace_key("robot1/alliance/motivation/wander")
    assert not ALLIANCE.is_coordination_key("robot1/alliance/agent")  # a token, not a message
    for key in ("robot1/murdoch/announcement", "robot1/murdoch/announcement/t1",
                "robot2/murdoch/bid/t1/robot1", "robot3/murdoch/claim"):
        assert MURDOCH.is_coordination_key(key), key
    assert not MURDOCH.is_coordination_key("robot1/murdoch")
    assert not MURDOCH.is_coordination_key("robot1/delivery/done")

    from mrta_supervisor.mission.analysis import message_rates
    records = [(k, "", 0, b"") for k in (
        "robot1/alliance/inter_robot_communication", "robot2/alliance/inter_robot_communication",
        "robot1/alliance/motivation/wander", "robot1/alliance/motivation/report",
        "robot1/alliance/sensory_feedback/wander", "robot1/odom", "robot2/odom",
        "@/liveliness/robot1/alliance/agent", "robot1/murdoch/announcement/t1")]
    rates = message_rates(records, ALLIANCE, 2.0)
    # all samples (liveliness aside) / the two broadcasts / everything under robotN/alliance/
    assert (rates.total_per_second, rates.coordination_per_second,
            rates.namespace_per_second) == (4.0, 1.0, 2.5)
    assert rates.coordination_kinds == ["inter_robot_communication"]
    rates = message_rates(records, MURDOCH, 1.0)
    assert (rates.coordination_per_second, rates.namespace_per_second) == (1.0, 1.0)
    # with log times: only [0, seconds) counts — the last instant holds what processes say as
    # they stop, recorded or not by a race (the same seed gave two rates)
    timed = [(k, "", int(t * 1e9), b"") for k, t in (
        ("robot1/alliance/inter_robot_communication", 0.0), ("robot1/odom", 1.9),
        ("robot1/alliance/inter_robot_communication", 2.0), ("robot1/cmd_vel", 2.0))]
    rates = message_rates(timed, ALLIANCE, 2.0, lambda t: t / 1e9)
    assert (rates.total_per_second, rates.coordination_per_second) == (1.0, 0.5)


def test_coordination_kinds_outside_the_messages_are_refused_at_load(monkeypatch):
    class Chatty(type(ALLIANCE)):
        name = "chatty"
        coordination_kinds = ("inter_robot_communication", "gossip")

    class EntryPoint:
        value = "tests:Chatty"

        def load(self):
            return Chatty

    monkeypatch.setattr(architectures, "_loaded", {})
    monkeypatch.setattr(architectures, "_entry_points", lambda: {"chatty": EntryPoint()})
    with pytest.raises(ConfigError, match="coordination_kinds gossip are not among its messages"):
        architecture("chatty")


def test_who_is_doing_what_is_read_from_each_architectures_own_messages():
    mot = Motivation(Header("robot1", 12.5, 3), "wander", 1.0, False, False, False, True,
                     100.0, 100.0, True)
    assert ALLIANCE.read_doing("robot1/alliance/motivation/wander", mot) == \
        Doing("robot1", "wander", True, 12.5)
    # a sample on robot1's key claiming to be robot2 says nothing
    assert ALLIANCE.read_doing("robot2/alliance/motivation/wander", mot) is None
    # broadcasts are coordination, not the feed
    irc = InterRobotCommunication(Header("robot1", 1.0, 1), "wander", 10.0)
    assert ALLIANCE.read_doing("robot1/alliance/inter_robot_communication", irc) is None
    claim = Claim(Header("robot3", 4.0, 1), "report", 3.5, 2.0)
    release = Release(Header("robot3", 9.0, 2), "report", "no progress")
    assert MURDOCH.read_doing("robot3/murdoch/claim", claim) == Doing("robot3", "report", True, 4.0)
    assert MURDOCH.read_doing("robot3/murdoch/release", release) == \
        Doing("robot3", "report", False, 9.0)


def test_the_takeover_bounds_are_the_architectures_formulas():
    patrol = ROOT / "configs" / "applications"
    assert ALLIANCE.takeover_bound(patrol / "patrol" / "config" / "robot3_alliance_params.yaml",
                                   "border_protection") == pytest.approx(4.5)
    assert MURDOCH.takeover_bound(
        patrol / "patrol_murdoch" / "config" / "robot3_murdoch_params.yaml", "wander") == \
        pytest.approx(2.8)
    with pytest.raises(ConfigError, match="no behaviour set for task 'nope'"):
        ALLIANCE.takeover_bound(patrol / "patrol" / "config" / "robot3_alliance_params.yaml",
                                "nope")


def test_an_application_under_another_architecture_is_its_package_for_that_architecture(
        fixed, monkeypatch):
    assert resolve(MissionOptions("patrol")).package.name == "patrol"
    from mrta_zenoh.toolchain import registry
    read, load = [], registry.load_rqt_mrta
    monkeypatch.setattr(registry, "load_rqt_mrta", lambda f: read.append(f.parent.name) or load(f))
    run = resolve(MissionOptions("patrol", "murdoch"))
    assert "patrol" not in read and "patrol_murdoch" in read  # the own package set aside unread
    assert (run.package.name, run.arch.name, run.mission.name) == ("patrol_murdoch", "murdoch",
                                                                   "patrol")
    run = resolve(MissionOptions("patrol", "fixed"))
    assert (run.package.name, run.arch, run.mission.name) == ("patrol_fixed", fixed, "patrol")
    assert run.robot_params("robot3") == PATROL_FIXED / "robot3_fixed_params.yaml"
    with pytest.raises(ConfigError, match="no architecture 'nope'"):
        resolve(MissionOptions("patrol", "nope"))


def fixed_team(fixed):
    net = InProcBus()
    clock = ManualClock(0.0)
    agents = {}
    for rid in ("robot2", "robot3"):
        prepared = fixed.prepare(AgentOptions(rid, PATROL_FIXED / f"{rid}_fixed_params.yaml",
                                              PATROL_FIXED / "tasks_fixed_params.yaml"))
        prepared.plugins.layers.clear()  # the patrol layers are not under test here
        agent = fixed.agent(prepared, net, clock, np.random.default_rng(0))
        agent.start()
        agent.declare_alive()
        agents[rid] = agent
    return net, clock, agents


def test_the_driver_runs_a_third_architecture_and_its_standby_takes_over(fixed):
    bus, clock, agents = fixed_team(fixed)
    heard = []
    bus.subscribe("*/fixed/doing", heard.append)
    for _ in range(10):
        for a in agents.values():
            a.tick_high(clock.now())
        clock.advance(0.1)
    assert agents["robot3"].active_task == "report"
    assert agents["robot3"].team == {"robot2"} and agents["robot2"].team == {"robot3"}
    # headers carry the sender, its time and a sequence number per key (the driver's job)
    mine = [s.message.header for s in heard if s.key == "robot2/fixed/doing"]
    assert [h.seq for h in mine] == list(range(1, len(mine) + 1))
    assert all(h.frame_id == "robot2" for h in mine)
    last_word = mine[-1].stamp
    del agents["robot2"]  # robot2 stops talking
    took = None
    while clock.now() < 10.0:
        agents["robot3"].tick_high(clock.now())
        if took is None and agents["robot3"].active_task == "border_protection":
            took = clock.now()
        clock.advance(0.1)
    bound = fixed.takeover_bound(PATROL_FIXED / "robot3_fixed_params.yaml", "border_protection")
    assert took is not None and 2.0 < took - last_word <= bound + 1e-9


@pytest.mark.slow
def test_the_driver_drops_forgers_and_strangers_and_counts_them(fixed):
    bus, clock, agents = fixed_team(fixed)
    from fixed_arch import DoingMsg
    bus.publish("robot2/fixed/doing", DoingMsg(Header("robot9", 0.0, 1), "report"))
    bus.publish("robot9/fixed/doing", DoingMsg(Header("robot9", 0.0, 1), "border_protection"))
    agents["robot3"].tick_high(clock.now())
    assert agents["robot3"].ignored_mismatch == 1 and agents["robot3"].ignored_strangers == 1
    assert "border_protection" not in agents["robot3"].coordinator.heard


@pytest.mark.slow
def test_decision_history_and_inbox_are_bounded():
    """A robot runs for days: what the agent keeps for inspection must not grow for ever."""
    from mrta_agent.alliance.agent import HISTORY
    prepared = ALLIANCE.prepare(AgentOptions(
        "robot1", ROOT / "configs/applications/patrol/config/robot1_alliance_params.yaml",
        ROOT / "configs/applications/patrol/config/tasks_alliance_params.yaml"))
    coord = ALLIANCE.coordinator(prepared)
    for i in range(HISTORY + 50):
        coord.history.append((float(i), None))
    assert len(coord.history) == HISTORY
    agent = ALLIANCE.agent(prepared, InProcBus(), ManualClock())
    for i in range(tokens.MAX_TOKENS + 10):  # invented robots: tracked up to a bound, counted
        agent._on_token(f"robot{i}/alliance/agent", True)
    assert len(agent.tokens.alive) == tokens.MAX_TOKENS and agent.tokens.ignored == 10


def test_a_flood_of_strangers_neither_fills_the_inbox_nor_pushes_teammates_out():
    """Strangers are dropped before they take inbox space, and tokens live apart from the
    bounded inbox: 20,000 forged broadcasts cannot make a teammate a stranger."""
    prepared = ALLIANCE.prepare(AgentOptions(
        "/robot1", ROOT / "configs/applications/patrol/config/robot1_alliance_params.yaml",
        ROOT / "configs/applications/patrol/config/tasks_alliance_params.yaml"))
    assert prepared.robot_id == "robot1"  # one spelling of the id, for the logic too
    bus, clock = InProcBus(), ManualClock(0.0)
    agent = ALLIANCE.agent(prepared, bus, clock)
    agent.start()
    token = bus.declare_token("robot2/alliance/agent")
    for i in range(20_000):
        bus.publish("robot9/alliance/inter_robot_communication",
                    InterRobotCommunication(Header("robot9", 0.0, i), "wander", 10.0))
    bus.publish("robot2/alliance/inter_robot_communication",
                InterRobotCommunication(Header("robot2", 0.0, 1), "wander", 10.0, 0.0))
    assert len(agent._inbox) == 1 and agent.ignored_strangers == 20_000
    agent.tick_high(clock.now())
    assert agent.team == {"robot2"} and "robot2" in agent.coordinator.high.sets["wander"].others
    token.close()
    agent.shutdown()


def test_plugins_registered_under_the_legacy_group_are_still_found(tmp_path, monkeypatch):
    (tmp_path / "legacy_plugin.py").write_text(
        "from mrta_agent.runtime.plugins import Layer\nclass Old(Layer):\n    pass\n")
    dist = tmp_path / "legacy_plugin-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: legacy-plugin\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(
        "[mrta.alliance.layers]\nlegacy/old = legacy_plugin:Old\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert load_plugin("layer", "legacy/old").__name__ == "Old"
    assert load_plugin("layer", "patrol/wander").__name__ == "Wander"  # the current group


@pytest.mark.slow
@pytest.mark.multiprocess
def test_mrta_demo_runs_the_patrol_mission_under_the_test_architecture(children, tmp_path):
    """The contract is enough: nothing outside tests/ knows `fixed`."""
    out = tmp_path / "demo"
    children.env["PYTHONPATH"] = os.pathsep.join(
        [str(PLUGINS), *filter(None, [os.environ.get("PYTHONPATH")])])
    s = children.demo(out, "--architecture", "fixed", "--duration", "16", "--fail", "robot2@6",
                      quiet=True).summary(150)
    assert (s["mission"], s["application"], s["architecture"]) == ("patrol", "patrol_fixed",
                                                                  "fixed")
    assert [x["task"] for x in s["who_did_what"]["robot1"]] == ["wander"]
    f = s["failure"]
    assert f["task"] == "border_protection" and f["taken_over_by"] == "robot3"
    assert f["takeover_seconds"] <= f["bound_seconds"] == pytest.approx(2.6)
    assert s["metrics"]["collisions_total"] == 0 and s["messages"]["coordination_namespace"] == "fixed"


def test_the_motivation_sample_where_a_robot_starts_or_stops_a_task_is_not_lossy(tmp_path):
    """Motivations are monitoring (lossy: a stopped observer must not stall a robot), but the
    ground truth reads who does what from them: the sample where `active` changes must reach
    the recorder even when it falls behind, or a takeover is measured a tick late."""
    from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write
    from tests.test_agent_inproc import feed
    rf = write(tmp_path / "r.yaml", robot_yaml([{"task": "a", "fast": 50.0}], spin=10.0,
                                                broadcast=5.0, tau=1.0))
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    bus, clock = InProcBus(), ManualClock(0.0)
    agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions("robot1", rf, tf)), bus, clock)
    sent = []
    publish = bus.publish
    bus.publish = lambda key, msg, lossy=False: (sent.append((key, msg, lossy)),
                                                 publish(key, msg, lossy=lossy))
    agent.start()
    for _ in range(5):  # θ = 100 at 50 per tick: active on the second tick
        feed(bus, clock)  # fresh sensors: the task is applicable
        agent.tick_high(clock.now())
        clock.advance(0.1)
    mot = [(m.active, lossy) for key, m, lossy in sent if "/motivation/" in key]
    assert mot == [(False, False), (True, False), (True, True), (True, True), (True, True)]
    agent.shutdown()
