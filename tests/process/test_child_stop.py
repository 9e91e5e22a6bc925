"""A child's stop (mrta_zenoh.processes.Child.stop): SIGINT, SIGKILL after the grace, and then
its end waited for however long the kernel takes — never a TimeoutExpired out of a run that
finished (issue 47: a 100-robot host at load 41 took over 5 s to go after its SIGKILL)."""

import signal
import sys

import pytest

from mrta_zenoh.processes import Child

pytestmark = pytest.mark.multiprocess

STUBBORN = ("import signal, time; signal.signal(signal.SIGINT, signal.SIG_IGN); "
            "print('up', flush=True); time.sleep(120)")


def test_a_child_deaf_to_sigint_is_killed_and_its_end_waited_for():
    child = Child([sys.executable, "-c", STUBBORN], name="stubborn")
    try:
        child.wait_line(lambda line: "up" in line, 60)
        # no grace at all: the SIGKILLed process is surely not reaped at the first look
        assert child.stop(grace=0.0) == -signal.SIGKILL
        assert child.signalled >= {signal.SIGINT, signal.SIGKILL}
    finally:
        if child.proc.poll() is None:
            child.proc.kill()
            child.proc.wait()
