"""The recorder's native crash: `mrta record` (and the demo's recorder) killed by SIGSEGV with no
stack, under load. msgspec (0.22) crashes the process when two threads build one Struct's type
information at once; the recorder's writer thread built it, without the codec's lock, to write
a new channel's JSON Schema (msgspec.json.schema makes a Decoder of the type) while Zenoh's
threads built the same types' decoders for their first samples. Run in a child process, because
the failure is a segfault; a fresh type each round, so each round builds it anew."""

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
from mrta_zenoh.recording import json_channel

sys.setswitchinterval(1e-6)
for it in range(800):
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

    def writer():  # the recorder's writer thread: a new channel's schema and converter
        start.wait()
        (_, _, schema), convert = json_channel(enc)
        got.append(b'"distance"' in schema and b'"distance":1.0' in convert(payload))

    def network():  # a Zenoh thread: the first sample of the type, decoded
        start.wait()
        got.append(codec.decoder_for(enc)[1](payload).distance == 1.0)

    threads = [threading.Thread(target=f) for f in (writer, network) * 4]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert got == [True] * 8, got
print("ok")
"""


@pytest.mark.multiprocess
def test_schemas_built_beside_decoders_on_other_threads_do_not_crash_the_recorder():
    proc = subprocess.run([sys.executable, "-X", "faulthandler", "-c", CHILD],
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", (proc.returncode,
                                                                  proc.stderr[-2000:])
