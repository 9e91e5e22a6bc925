"""A run's faults are resolved once, into a typed value on the run (MissionRun.faults,
supervisor/mission/hook.py): `--fail` is parsed and checked when the run is resolved, `@random`
is drawn on that value (supervisor/mission/roles.py), and the runner reads the value from then
on — never the option text again. The mission's launch is replaced by a stand-in (no process)."""

from __future__ import annotations

import pytest

from mrta_zenoh import failure
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import RANDOM
from mrta_supervisor.mission import hook
from mrta_supervisor.mission import roles
from mrta_supervisor.mission import runner
from mrta_supervisor.mission.hook import MissionOptions, resolve


def test_random_is_drawn_on_the_typed_faults_and_the_option_text_stays_what_was_asked():
    asked = "stall:@random@5,loss:0.1"
    run = resolve(MissionOptions(application="delivery", architecture="ssi", fail=asked))
    assert run.faults.of(RANDOM) is not None and run.faults.loss == 0.1
    drawn = roles.with_random_drawn(run)
    robot = drawn.faults.primary.robot
    assert robot in run.robots and drawn.faults.of(RANDOM) is None
    assert drawn.faults.spec == f"stall:{robot}@5,loss:0.1" and drawn.faults.loss == 0.1
    assert drawn.options.fail == asked and run.faults.of(RANDOM) is not None  # nothing rewritten
    # drawn from the instance, so the same robot under another architecture and run seed
    other = resolve(MissionOptions(application="delivery", architecture="central", fail=asked,
                                   seed=9))
    assert roles.with_random_drawn(other).faults.primary.robot == robot


def test_a_run_without_random_is_the_same_run():
    run = resolve(MissionOptions(application="delivery", fail="crash:robot1@5"))
    assert roles.with_random_drawn(run) is run


def test_a_run_parses_its_fault_spec_once(tmp_path, monkeypatch):
    parsed, started = [], []
    real = hook.parse_faults

    def counting(spec):
        parsed.append(spec)
        return real(spec)

    def _run_in(run, reg, stop, progress, before):
        started.append(run)
        return run, None

    monkeypatch.setattr(hook, "parse_faults", counting)
    monkeypatch.setattr(failure, "parse_faults", counting)
    monkeypatch.setattr(runner, "_run_in", _run_in)
    runner.run_mission(MissionOptions(application="delivery", architecture="central",
                                      fail="crash:@random@5", output=tmp_path / "out"))
    assert parsed == ["crash:@random@5"]
    (run,) = started
    assert run.faults.primary.robot in run.robots and run.faults.spec.startswith("crash:robot")


def test_a_bad_spec_is_refused_when_the_run_is_resolved():
    with pytest.raises(ConfigError, match="is not one of"):
        resolve(MissionOptions(application="delivery", fail="crash:robot99@5"))


def test_a_stall_of_the_dispatcher_is_refused_naming_what_would_act():
    """`stall:dispatcher@5` was accepted and did nothing (issue 51): a stall stops a robot's
    layers, and the dispatcher has none."""
    with pytest.raises(ConfigError, match="dispatcher has none; crash it .dispatcher@5."):
        resolve(MissionOptions(application="delivery_central", fail="stall:dispatcher@5"))
    resolve(MissionOptions(application="delivery_central", fail="dispatcher@5"))
