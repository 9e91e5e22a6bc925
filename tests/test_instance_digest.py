"""Index-based messages say which instance they count in (mrta_zenoh.messages.IndexedMessage):
SSI's and CBBA's robots and tasks travel as indices into the instance, so a robot given another
instance would misread its teammates silently. The driver stamps its robot's instance digest on
every such message and refuses, counts and warns about one stamped with another."""

from __future__ import annotations

import logging
import shutil

import numpy as np
import pytest

from mrta_agent.runtime.host import AgentOptions
from mrta_zenoh import instances
from mrta_zenoh.architectures import architecture
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import IndexedMessage
from mrta_zenoh.refusal_tally import OTHER_INSTANCE
from tests.harness.helpers import CONFIGS

APPS = CONFIGS / "applications"


def other_instance(tmp_path, package: str):
    """A copy of the package whose instance differs in one service time: same robots, same
    tasks, same order — exactly the change indices cannot show."""
    pkg = tmp_path / package
    shutil.copytree(APPS / package, pkg)
    inst = pkg / "config" / "instance.yaml"
    inst.write_text(inst.read_text().replace("service: 3.0", "service: 3.5", 1))
    return pkg


def team(arch: str, packages: dict):
    """Agents of `arch` on one in-process bus and a manual clock, each from its own package
    (their delivery layers left out: only the coordination is under test)."""
    bus, clock, agents = InProcBus(), ManualClock(0.0), {}
    contract = architecture(arch)
    for rid, pkg in packages.items():
        config = pkg / "config"
        prepared = contract.prepare(AgentOptions(
            rid, config / f"{rid}_{arch}_params.yaml", config / f"tasks_{arch}_params.yaml",
            config / f"layers_{arch}_params.yaml"))
        prepared.plugins.layers.clear()
        agents[rid] = contract.agent(prepared, bus, clock, np.random.default_rng(0))
        agents[rid].start()
        agents[rid].declare_alive()
    return bus, clock, agents


def run(bus, clock, agents, ticks=30):
    said = []
    bus.subscribe("**", lambda s: said.append(s) if isinstance(s.message, IndexedMessage)
                  else None)
    for _ in range(ticks):
        for agent in agents.values():
            agent.tick_high(clock.now())
        clock.advance(0.1)
    return said


@pytest.mark.parametrize("arch", ["ssi", "cbba"])
def test_teammates_on_one_instance_hear_each_other(arch):
    pkg = APPS / f"delivery_{arch}"
    bus, clock, agents = team(arch, {"robot1": pkg, "robot2": pkg})
    said = run(bus, clock, agents)
    digest = instances.load(pkg / "config" / "instance.yaml").digest
    assert len(digest) == instances.DIGEST_LENGTH
    assert said and {s.message.instance for s in said} == {digest}
    assert all(a.ignored_other_instance == 0 for a in agents.values())


@pytest.mark.parametrize("arch", ["ssi", "cbba"])
def test_a_teammate_on_another_instance_is_refused_counted_and_named(arch, tmp_path, caplog):
    mine, theirs = APPS / f"delivery_{arch}", other_instance(tmp_path, f"delivery_{arch}")
    bus, clock, agents = team(arch, {"robot1": mine, "robot2": theirs})
    with caplog.at_level(logging.WARNING):
        said = run(bus, clock, agents)
    digests = {rid: a.instance_digest for rid, a in agents.items()}
    assert digests["robot1"] != digests["robot2"]
    # each says its own digest, and refuses every such message of the other's it hears (SSI's
    # robot2 never bids: it refused every Round of its auctioneer, robot1)
    assert {s.message.instance for s in said if s.key.startswith("robot1/")} \
        == {digests["robot1"]}
    for rid, agent in agents.items():
        assert {s.message.instance for s in said if s.key.startswith(rid + "/")} <= {digests[rid]}
        heard = [s for s in said if not s.key.startswith(rid + "/")
                 and (s.key.count("/") == 2 or s.key.endswith("/" + rid))]
        assert agent.ignored_other_instance == len(heard)
    assert agents["robot2"].ignored_other_instance > 0
    # and what it says it refused (every summary's `refused`) names the sender and the reason
    told = agents["robot2"].refusals.merged({})
    assert sum(n for (_, sender, reason, forged), n in told.items()
               if (sender, reason, forged) == ("robot1", OTHER_INSTANCE, False)) \
        == agents["robot2"].ignored_other_instance
    warned = [r.getMessage() for r in caplog.records if "two instances" in r.getMessage()]
    assert any(digests["robot1"] in w and digests["robot2"] in w for w in warned)
