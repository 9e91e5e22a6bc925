"""ROBOT@SECONDS: one grammar for an experiment's file, a mission's --fail and the agents'
$MRTA_FAULTS, so a spec accepted at one hop is never refused at the next; `--crash-at` is
shorthand for a crash item naming the agent itself."""

import pytest

from mrta_supervisor.mission.hook import parse_fail
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import (FAULTS_ENV, RETIRED_CRASH_ENV, Failure, FaultKind,
                                parse_failure, plan_from_env)

BAD = ["robot2@0", "robot2@0.0", "robot2@-1", "robot2@inf", "robot2@1e3", "robot2 at 5",
       "robot2@", "@30", "/robot2@30", "robot2@30@1", "r" * 65 + "@30", "robot2@30+5"]


@pytest.mark.parametrize("spec,robot,at", [("robot2@30", "robot2", 30.0),
                                           ("robot_1.a-b@0.25", "robot_1.a-b", 0.25)])
def test_good_specs_read_the_same_everywhere(spec, robot, at):
    assert parse_failure(spec) == Failure(robot, at, spec)
    assert parse_failure(spec).kind is FaultKind.CRASH
    assert parse_fail(spec).failures == (Failure(robot, at, spec),)
    env = {FAULTS_ENV: f"other@9,{spec}"}
    assert plan_from_env(robot, 0, environ=env).crash_at == at
    assert plan_from_env("robot9", 0, environ=env) is None


@pytest.mark.parametrize("spec", BAD)
def test_bad_specs_are_refused_everywhere(spec):
    with pytest.raises(ValueError, match="ROBOT@SECONDS"):
        parse_failure(spec)
    with pytest.raises(ConfigError, match="--fail .*ROBOT@SECONDS"):
        parse_fail(spec)
    with pytest.raises(ConfigError, match=f"\\${FAULTS_ENV}.*ROBOT@SECONDS"):
        plan_from_env("robot2", 0, environ={FAULTS_ENV: spec})


def test_none_means_no_failure_for_a_mission_only():
    assert parse_fail("none") is None and parse_fail(None) is None
    with pytest.raises(ConfigError):
        plan_from_env("robot2", 0, environ={FAULTS_ENV: "none"})


def test_crash_at_is_shorthand_for_a_crash_item_of_the_agent_itself():
    plan = plan_from_env("robot2", 7, crash_at=12.5, environ={FAULTS_ENV: "loss:0.1"})
    assert (plan.crash_at, plan.loss, plan.seed) == (12.5, 0.1, 7)
    assert not plan.crashed(12.4) and plan.crashed(12.5)
    assert plan_from_env("robot2", 0, crash_at=3.0, environ={}).crash_at == 3.0
    # one fault per robot, whichever way it came
    with pytest.raises(ConfigError, match="--crash-at.*robot2 already has a fault"):
        plan_from_env("robot2", 0, crash_at=3.0, environ={FAULTS_ENV: "stall:robot2@5"})


def test_the_retired_crash_variable_is_refused_not_ignored():
    """Every fault goes through $MRTA_FAULTS; a script still setting $MRTA_CRASH would
    otherwise run without the crash it asked for."""
    with pytest.raises(ConfigError, match=f"\\${RETIRED_CRASH_ENV} is not read.*"
                                          f"{FAULTS_ENV}=robot2@30"):
        plan_from_env("robot2", 0, environ={RETIRED_CRASH_ENV: "robot2@30"})
    assert plan_from_env("robot2", 0, environ={RETIRED_CRASH_ENV: ""}) is None
