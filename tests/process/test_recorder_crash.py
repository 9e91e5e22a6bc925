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
import msgspec
from mrta_zenoh import codec
from mrta_zenoh.messages import Header, Message, message
from mrta_zenoh.recording import json_channel

sys.setswitchinterval(1e-6)


def fresh_type(n: int):
    # a new message type (with a new nested one): its type information not built yet
    entry = msgspec.defstruct(f"Entry{n}", [("who", str), ("seconds", float)], bases=(Message,))
    fields = [("header", Header), ("distance", float), ("visited", bytes),
              ("entries", tuple[entry, ...])]
    cls = message(f"race_msgs/Log{n}")(msgspec.defstruct(f"Log{n}", fields, bases=(Message,)))
    return cls, cls(Header("r", 1.0, 1), 1.0, b"\x01", (entry("r", 1.0),))


for n in range(2000):
    cls, sample = fresh_type(n)
    enc, payload = codec.encoding_for(cls.TYPE_NAME), codec.encode(sample)
    start, got = threading.Barrier(8), []

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
@pytest.mark.slow
def test_schemas_built_beside_decoders_on_other_threads_do_not_crash_the_recorder():
    proc = subprocess.run([sys.executable, "-X", "faulthandler", "-c", CHILD],
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0 and proc.stdout.strip() == "ok", (proc.returncode,
                                                                  proc.stderr[-2000:])
