"""The fork server (mrta_zenoh.forkserver): a `python -m MODULE` child of a ProcessGroup that
names one is forked by it — the child is the server's, not a fresh interpreter — and behaves as
a fresh one would: its arguments, environment, working directory (first on sys.path, as `-m`
puts it), output, exit code and the signals its starter sends it; a child whose starter went
is ended. (An experiment's rows are the same either way: test_experiment_forkserver.py.)"""

from __future__ import annotations

import os
import signal
import sys
import textwrap
import time

import pytest

from mrta_zenoh import forkserver
from mrta_zenoh.forkserver import ForkedProcess
from mrta_zenoh.processes import ProcessGroup

PROBE = textwrap.dedent("""
    import os, sys, time
    print(os.getcwd(), os.environ.get("PROBE"), sys.argv[1:], os.getppid(), flush=True)
    print("to stderr", file=sys.stderr, flush=True)
    if sys.argv[1] == "sleep":
        time.sleep(60)
    sys.exit(int(sys.argv[1]) if sys.argv[1].isdigit() else 0)
""")


def _ppid(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as f:
        return int(f.read().rsplit(")", 1)[1].split()[1])


@pytest.mark.multiprocess
@pytest.mark.timeout(120)
def test_a_forked_child_runs_as_a_fresh_one_would(tmp_path):
    (tmp_path / "probe.py").write_text(PROBE)
    with ProcessGroup() as group:
        server = forkserver.ensure(group, ["json"], timeout=60)
        assert forkserver.ensure(group, ["json"]) is server  # one a group
        child = group.start([sys.executable, "-m", "probe", "3"], name="probe", cwd=tmp_path,
                            env={"PROBE": "here"})
        assert isinstance(child.proc, ForkedProcess)
        assert child.wait(30) == 3 and child.failed()
        cwd, probe, argv, ppid = child.stdout[0].split(" ", 3)
        assert (cwd, probe, argv) == (str(tmp_path), "here", "['3']")
        assert int(ppid) == server.pid  # forked by the server
        assert child.stderr == ["to stderr"]

        sleeper = group.start([sys.executable, "-m", "probe", "sleep"], name="sleeper",
                              cwd=tmp_path)
        sleeper.wait_line(lambda line: "sleep" in line, 30)
        assert sleeper.running() and _ppid(sleeper.pid) == server.pid
        assert sleeper.stop(grace=60) == -signal.SIGINT  # as a fresh one ends (60: a hang guard)
        assert sleeper.stopped_by_us() and sleeper.describe_exit() == "stopped"

        # another interpreter's command, or not `-m`: started fresh, as always
        fresh = group.start([sys.executable, str(tmp_path / "probe.py"), "0"], name="fresh")
        assert not isinstance(fresh.proc, ForkedProcess) and fresh.wait(30) == 0

        # a starter that goes (its connection closes) takes its child with it
        orphan = ForkedProcess([sys.executable, "-m", "probe", "sleep"], group.env,
                               str(tmp_path), True)
        assert orphan.stdout.readline()
        orphan._conn.close()
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and _alive(orphan.pid, server.pid):
            time.sleep(0.05)
        assert not _alive(orphan.pid, server.pid)
        forkserver.finish(group)
        assert server.returncode == 0 and server.stdout[-1] == f"{forkserver.FORKED} 3"


def _alive(pid: int, parent: int) -> bool:
    """Still a running child of `parent` (not yet reaped, nor a zombie)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except FileNotFoundError:
        return False
    return fields[0] != "Z" and int(fields[1]) == parent and os.path.exists(f"/proc/{pid}")
