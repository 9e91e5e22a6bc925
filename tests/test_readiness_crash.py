"""A crash the run injected can strike before the runner saw every process up (lockstep at
full speed on a busy machine): the crashed subject is no start-up failure; any other is."""

from __future__ import annotations

import threading

import pytest

from mrta_supervisor.mission.run_watch import Readiness
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.errors import MrtaRuntimeError


class Dead:
    name = "robot2/alliance"

    def failed(self) -> bool:
        return True

    def describe_exit(self) -> str:
        return "killed by SIGKILL"

    def tail(self) -> str:
        return ""


class Group:
    children = [Dead()]

    def failed(self, ignore=()):
        return [c for c in self.children if c.name not in set(ignore) and c.failed()]


def test_a_crashed_subject_is_no_start_up_failure_but_any_other_is():
    with InProcBus() as bus:
        ready = Readiness(bus, ["robot1", "robot2"])
        polls = iter(range(3))
        ready.wait(lambda: next(polls) == 2, "the robots' agents", Group(), threading.Event(),
                   ignore=lambda: ["robot2/alliance"])
        with pytest.raises(MrtaRuntimeError, match="robot2/alliance failed while starting"):
            ready.wait(lambda: False, "the robots' agents", Group(), threading.Event())
        ready.close()
