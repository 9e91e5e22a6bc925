"""`mrta record` when its file cannot be written: into a read-only folder it exits
2 up front, with one line; when the disk fills while it records (here a file size limit,
RLIMIT_FSIZE, through `prlimit`: no mount needed) it exits 1 at once, saying how much it wrote
— not "recording stops" and running on, recording nothing, until signalled."""

from __future__ import annotations

import os
import shutil
import sys
import tempfile

import pytest

from tests.harness.helpers import Child

pytestmark = pytest.mark.multiprocess


@pytest.mark.slow
def test_a_read_only_folder_is_exit_2_up_front_in_one_line(children):
    folder = tempfile.mkdtemp(prefix="mrta-ro-")
    try:
        os.chmod(folder, 0o555)  # as root, permissions do not bind: the child runs as nobody
        as_nobody = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"] \
            if os.geteuid() == 0 else []
        rec = Child([*as_nobody, sys.executable, "-m", "mrta_zenoh.cli.main", "record", "-o",
                     os.path.join(folder, "run.mcap"), "--duration", "30"], children.env,
                    "record")
        children.all.append(rec)
        assert rec.wait(60) == 2, rec.tail()
        lines = [line for line in rec.stderr if line.strip()]
        assert len(lines) == 1 and "not writable" in lines[0] and folder in lines[0], lines
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.mark.slow
@pytest.mark.timeout(180)
def test_a_full_disk_stops_the_recorder_at_once_with_exit_1(children, tokens, tmp_path):
    sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--robot", "robot2",
                        "--speed", "4", name="sim")
    tokens.wait("@mrta/clock_source/*", 60, sim)
    out = tmp_path / "run.mcap"
    rec = Child(["prlimit", "--fsize=300000", sys.executable, "-m", "mrta_zenoh.cli.main",
                 "record", "-o", str(out), "--duration", "120"], children.env, "record")
    children.all.append(rec)
    # the simulator's sonar, odometry and truth fill 300 kB in a few seconds; without the fix
    # the recorder ran on to its --duration
    assert rec.wait(90) == 1, rec.tail()
    said = "\n".join(rec.stderr)
    assert "cannot write the recording" in said and "lost" in said, said[-2000:]
    assert "Traceback" not in said
    assert 0 < out.stat().st_size <= 300000
