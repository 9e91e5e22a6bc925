"""Two SSI robots on real Zenoh sessions, each its own process, given different instances (the
same robots and tasks in the same order: one service time differs — what indices cannot show).
The robot that hears the other's index-based message refuses it and says so, naming both
instances' digests, instead of bidding on a Round it would misread (tests/test_instance_digest.py
has the in-process cases)."""

from __future__ import annotations

import shutil

import pytest

from mrta_zenoh import instances
from tests.harness.helpers import CONFIGS

pytestmark = pytest.mark.multiprocess

PACKAGE = CONFIGS / "applications" / "delivery_ssi"


def agent(children, robot: str, config):
    return children.mrta("ssi", robot, "--robot-params", config / f"{robot}_ssi_params.yaml",
                         "--tasks-params", config / "tasks_ssi_params.yaml",
                         "--layers-params", config / "layers_ssi_params.yaml",
                         "--team", "robot1,robot2", "--duration", "60", name=robot)


@pytest.mark.timeout(120)
def test_a_robot_on_another_instance_is_refused_and_named_across_processes(children, tokens,
                                                                        tmp_path):
    other = tmp_path / "delivery_ssi"
    shutil.copytree(PACKAGE, other)
    inst = other / "config" / "instance.yaml"
    inst.write_text(inst.read_text().replace("service: 3.0", "service: 3.5", 1))
    mine = instances.load(PACKAGE / "config" / "instance.yaml").digest
    theirs = instances.load(inst).digest
    assert mine != theirs
    robot1 = agent(children, "robot1", PACKAGE / "config")  # the auctioneer: the lowest id
    robot2 = agent(children, "robot2", other / "config")
    tokens.wait_all(["robot1/ssi/agent", "robot2/ssi/agent"], 60, robot1, robot2)
    line = robot2.wait_stderr(lambda s: "the team runs two instances" in s, 60)
    assert "ignoring Round from robot1" in line and mine in line and theirs in line
