"""Decoders built from several threads at once (Zenoh delivers samples on several): msgspec
0.22 crashes the process when two threads build a Struct's type information together, so
mrta_zenoh.codec builds each type's decoder under a lock. Run in a child process, because the
failure is a segfault."""

from __future__ import annotations

import subprocess
import sys

import pytest

CHILD = r"""
import sys, threading
from typing import Annotated
import msgspec
from mrta_zenoh import codec
from mrta_zenoh.messages import Header, Message, message

sys.setswitchinterval(1e-6)
for it in range(300):
    class TaskTime(Message):
        robot_id: str
        seconds: Annotated[float, msgspec.Meta(ge=0)]

    @message(f"race_msgs/Log{it}")
    class Log(Message):
        header: Header
        distance: Annotated[float, msgspec.Meta(ge=0.0)]
        visited: bytes
        task_times: tuple[TaskTime, ...]

    enc = codec.encoding_for(Log.TYPE_NAME)
    payload = codec.encode(Log(Header("r", 1.0, 1), 1.0, b"\x01", (TaskTime("r", 1.0),)))
    start = threading.Barrier(8)
    got = []

    def work():
        start.wait()
        got.append(codec.decoder_for(enc)[1](payload).distance)

    threads = [threading.Thread(target=work) for _ in range(8)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert got == [1.0] * 8, got
print("ok")
"""


@pytest.mark.slow
@pytest.mark.multiprocess
def test_eight_threads_building_a_new_types_decoder_at_once_do_not_crash():
    proc = subprocess.run([sys.executable, "-c", CHILD], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", (proc.returncode, proc.stderr)
