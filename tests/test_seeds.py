"""One derivation of every random number of a run (mrta_zenoh.seeds): each draw is named by a
path below the run's seed — streams through numpy's SeedSequence with the names' CRC-32 as
spawn keys, per-event draws through a BLAKE2b hash of the same path. Each expectation is
computed here from the documented definition, not by the code under test."""

import hashlib
import zlib

import numpy as np
import pytest

from mrta_simulator.engine import Simulation
from mrta_simulator.world import Pose, World
from mrta_zenoh.failure import FaultPlan
from mrta_zenoh.seeds import SEED_ENV, generator, robot_rng, stream, uniform


def by_definition(seed: int, *path: str) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(
        entropy=seed, spawn_key=tuple(zlib.crc32(p.encode()) for p in path)))


@pytest.mark.parametrize("seed", [0, 3, 2**62])
def test_the_simulator_draws_from_the_root_and_each_robot_from_its_own_name(seed):
    world = World(name="empty", walls=np.zeros((0, 4)))
    sim = Simulation(world, {"robot1": Pose(0.0, 0.0, 0.0), "robot2": Pose(2.0, 0.0, 0.0)},
                     seed=seed)
    root = by_definition(seed)  # the simulator's first draws: each robot's odometry bias
    m = sim.model
    assert sim._odom_bias[:, 0].tolist() == (1.0 + root.normal(0.0, m.odom_scale_sigma, 2)).tolist()
    assert sim._odom_bias[:, 1].tolist() == (1.0 + root.normal(0.0, m.odom_turn_sigma, 2)).tolist()
    assert sim.rng.normal(size=8).tolist() == root.normal(size=8).tolist()
    assert generator(seed).integers(0, 2**32, 4).tolist() == \
        np.random.default_rng(seed).integers(0, 2**32, 4).tolist()  # the root is default_rng
    for robot in ("robot1", "robot2"):
        assert robot_rng(seed, robot).normal(size=4).tolist() == \
            by_definition(seed, robot).normal(size=4).tolist()
    assert stream(seed, "a", "b").random() == by_definition(seed, "a", "b").random()
    # distinct names, distinct numbers; the root is none of its children
    draws = {tuple(s.random(3)) for s in (generator(seed), robot_rng(seed, "robot1"),
                                          robot_rng(seed, "robot2"), stream(seed, "instance"))}
    assert len(draws) == 4


def test_a_per_event_draw_is_the_hash_of_its_path_and_fault_draws_use_it():
    def by_hash(*parts):
        digest = hashlib.blake2b("\0".join(map(str, parts)).encode(), digest_size=8).digest()
        return int.from_bytes(digest, "big") / 2.0 ** 64

    assert uniform(42, "loss", "robot1", "robot2/alliance/x", 7) == \
        by_hash(42, "loss", "robot1", "robot2/alliance/x", 7)
    plan = FaultPlan("robot1", 42, loss=0.5, latency=(0.3, 0.2))
    for seq in range(200):
        key = "robot2/alliance/inter_robot_communication"
        assert plan.lost(key, seq) == (by_hash(42, "loss", "robot1", key, seq) < 0.5)
        assert plan.delay(key, seq) == pytest.approx(
            0.3 + 0.2 * (2 * by_hash(42, "latency", "robot1", key, seq) - 1))


def test_the_seed_reaches_every_verb_through_one_variable(monkeypatch):
    """The runner sets $MRTA_SEED for every process it starts; each verb's --seed reads it,
    so a node whose launch text forgot the seed still draws from the run's."""
    from click.testing import CliRunner

    from mrta_agent.alliance.architecture import ALLIANCE
    from mrta_agent.runtime import cli
    from mrta_simulator import cli as sim_cli

    seen = []
    monkeypatch.setattr(ALLIANCE, "run", lambda options, stop=None: seen.append(options.seed))
    monkeypatch.setattr(sim_cli, "run_simulator",
                        lambda options, bus_options: seen.append(options.seed))
    runner = CliRunner()
    agent = cli.agent_command(ALLIANCE, "help")
    args = ["robot1", "--robot-params", "r", "--tasks-params", "t"]
    assert runner.invoke(agent, args, env={SEED_ENV: "17"}).exit_code == 0
    assert runner.invoke(agent, args + ["--seed", "4"], env={SEED_ENV: "17"}).exit_code == 0
    assert runner.invoke(agent, args, env={SEED_ENV: None}).exit_code == 0
    sim_args = ["--world", "patrol", "--robot", "robot1"]
    assert runner.invoke(sim_cli.sim, sim_args, env={SEED_ENV: "17"}).exit_code == 0
    assert seen == [17, 4, 0, 17]
