"""ROBOT@SECONDS: one grammar for an experiment's file, a mission's --fail and $MRTA_CRASH, so a
spec accepted at one hop is never refused at the next."""

import pytest

from mrta_supervisor.mission import parse_fail
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import Failure, parse_failure
from mrta_agent.runtime.host import CRASH_ENV, crash_time

BAD = ["robot2@0", "robot2@0.0", "robot2@-1", "robot2@inf", "robot2@1e3", "robot2 at 5",
       "robot2@", "@30", "/robot2@30", "robot2@30@1", "r" * 65 + "@30"]


@pytest.mark.parametrize("spec,robot,at", [("robot2@30", "robot2", 30.0),
                                           ("robot_1.a-b@0.25", "robot_1.a-b", 0.25)])
def test_good_specs_read_the_same_everywhere(spec, robot, at, monkeypatch):
    assert parse_failure(spec) == Failure(robot, at, spec)
    assert parse_fail(spec).failures == (Failure(robot, at, spec),)
    monkeypatch.setenv(CRASH_ENV, f"other@9,{spec}")
    assert crash_time(robot, None) == at and crash_time("robot9", None) is None


@pytest.mark.parametrize("spec", BAD)
def test_bad_specs_are_refused_everywhere(spec, monkeypatch):
    with pytest.raises(ValueError, match="ROBOT@SECONDS"):
        parse_failure(spec)
    with pytest.raises(ConfigError, match="--fail .*ROBOT@SECONDS"):
        parse_fail(spec)
    monkeypatch.setenv(CRASH_ENV, spec)
    with pytest.raises(ConfigError, match=f"\\${CRASH_ENV}.*ROBOT@SECONDS"):
        crash_time("robot2", None)


def test_none_means_no_failure_for_a_mission_only(monkeypatch):
    assert parse_fail("none") is None and parse_fail(None) is None
    monkeypatch.setenv(CRASH_ENV, "none")
    with pytest.raises(ConfigError):
        crash_time("robot2", None)
