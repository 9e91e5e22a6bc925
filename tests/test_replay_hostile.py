"""`mrta replay` on crafted recordings: never a traceback, never an endless wait (issue #23:
a topic `a//b`, a liveliness payload `[1]`, log times 0 and 2⁶⁴−1 made tracebacks or a 31-year
wait). The replay is planned before a session opens (tools/replay.plan_replay), so the timing
is checked without waiting and the rest on the in-process bus."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import msgpack
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings, strategies as st
from mcap.writer import Writer

from mrta_zenoh.bus.inproc import InProcBus
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import LIVELINESS_PREFIX
from mrta_zenoh.recording import read_recording
from mrta_zenoh.tools.replay import MAX_GAP, plan_replay, run_replay

IRC = "application/msgpack;alliance_msgs/InterRobotCommunication"
GOOD = msgpack.packb({"header": {"frame_id": "robot1", "stamp": 1.0, "seq": 0},
                      "task_id": "wander", "expected_duration": 12.0})
U64 = 2**64 - 1


def craft(path, items) -> None:
    """An MCAP file of (topic, zenoh encoding, message encoding, type, log time, data)."""
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        chans: dict = {}
        for topic, enc, msg_enc, type_name, t, data in items:
            ident = (topic, enc, msg_enc, type_name)
            if ident not in chans:
                chans[ident] = w.register_channel(topic=topic, message_encoding=msg_enc,
                                                  schema_id=0,
                                                  metadata={"encoding": enc, "type": type_name})
            w.add_message(channel_id=chans[ident], log_time=t, publish_time=t, data=data)
        w.finish()


def replay_inproc(path, **kw) -> tuple[int, list]:
    """run_replay on an in-process bus at full speed; (samples sent, samples seen)."""
    bus = InProcBus()
    seen: list = []
    bus.subscribe_raw("**", lambda s: seen.append((s.key, s.payload)))
    sent = run_replay(recording=path, bus_options=None, speed=0, bus=bus,
                      stop=threading.Event(), **kw)
    return sent, seen


def test_the_issues_crafted_recordings_replay_what_is_valid_and_skip_the_rest(tmp_path, caplog):
    f = tmp_path / "crafted.mcap"
    craft(f, [("a//b", IRC, "msgpack", "", 0, GOOD),
              ("robot1/alliance/inter_robot_communication", IRC, "msgpack", "", 1, GOOD),
              ("**", IRC, "msgpack", "", 2, GOOD),
              (LIVELINESS_PREFIX + "robot1/alliance/agent", "application/json", "json", "", 3,
               b"[1]"),
              (LIVELINESS_PREFIX + "robot1/x", "application/json", "json", "", 4, b"\xff{"),
              ("robot1/alliance/inter_robot_communication", IRC, "msgpack", "", U64, GOOD)])
    sent, seen = replay_inproc(f)
    assert sent == 2 and [k for k, _ in seen] == ["robot1/alliance/inter_robot_communication"] * 2
    text = caplog.text
    assert "skipped 2 records: not a concrete key (first: 'a//b')" in text
    assert "skipped 2 records: liveliness payload" in text
    assert f"shortened 1 silences longer than {MAX_GAP:g} s" in text


def test_a_31_year_silence_is_shortened_to_the_maximum_gap():
    records = [("k", IRC, 1, GOOD), ("k", IRC, 10**18, GOOD), ("k", IRC, U64, GOOD)]
    plan = plan_replay(records)
    assert [s.at for s in plan.steps] == [0.0, MAX_GAP, 2 * MAX_GAP] and plan.shortened == 2
    assert plan_replay(records, max_gap=5).span == 10.0


def test_a_bad_max_gap_is_bad_input(tmp_path):
    f = tmp_path / "r.mcap"
    craft(f, [("k", IRC, "msgpack", "", 1, GOOD)])
    res = CliRunner().invoke(cli, ["replay", str(f), "--max-gap", "1e308"])
    assert res.exit_code == 2 and "must be between 0.001 and 604800 s" in res.output, res.output


TOPICS = st.one_of(
    st.sampled_from(["robot1/alliance/inter_robot_communication", "clock", "a//b", "", "/",
                     "**", "a/*/b", "a/b*", "x/$*", "k/@x", "@mrta/lockstep/step", "a b", "a#b",
                     "robot1/" + "x" * 300]),
    st.text(max_size=30),
)
ENCODINGS = st.one_of(st.sampled_from([IRC, "application/json", "application/msgpack;",
                                       "application/msgpack;no_such/Type", ""]),
                      st.text(max_size=20))
TIMES = st.one_of(st.sampled_from([0, 1, U64, U64 - 1, 10**18]), st.integers(0, U64))
PAYLOADS = st.one_of(st.sampled_from([GOOD, b"", b"[1]", b"\xff{", b'{"alive": 1}',
                                      b'{"alive": true}', b'{"alive": false}', b"\xc1"]),
                     st.binary(max_size=40))
ITEM = st.tuples(
    st.one_of(TOPICS, TOPICS.map(lambda t: LIVELINESS_PREFIX + t)), ENCODINGS,
    st.sampled_from(["msgpack", "json", "cdr", ""]),
    st.sampled_from(["", "alliance_msgs/InterRobotCommunication", "rosgraph_msgs/Clock",
                     "no/Such"]),
    TIMES, PAYLOADS)


@pytest.mark.slow
@settings(max_examples=150, derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture,
                                 HealthCheck.too_slow])
@given(items=st.lists(ITEM, min_size=1, max_size=12))
def test_any_crafted_recording_replays_or_is_refused_and_never_waits_long(tmp_path, items):
    f = tmp_path / "hostile.mcap"
    craft(f, items)
    try:
        records = read_recording(f)
    except ConfigError:
        return  # refused as a whole, with a line naming the file: fine
    plan = plan_replay(records, clock=True)
    # the whole replay at speed 1 lasts at most one maximum gap per record
    assert 0 <= plan.span <= MAX_GAP * max(0, len(records) - 1)
    assert [s.at for s in plan.steps] == sorted(s.at for s in plan.steps)
    try:
        sent, seen = replay_inproc(f, clock=True)
    except ConfigError:
        return
    assert sent == sum(1 for s in plan.steps if s.alive is None) == len(seen)


def test_liveliness_changes_are_replayed_as_tokens(tmp_path):
    f = tmp_path / "tokens.mcap"
    key = "robot1/alliance/agent"
    craft(f, [(LIVELINESS_PREFIX + key, "application/json", "json", "", 1,
               json.dumps({"alive": True}).encode()),
              ("robot1/alliance/inter_robot_communication", IRC, "msgpack", "", 2, GOOD),
              (LIVELINESS_PREFIX + key, "application/json", "json", "", 3,
               json.dumps({"alive": False}).encode())])
    bus = InProcBus()
    changes: list = []
    bus.watch_liveliness("**", lambda k, up: changes.append((k, up)))
    run_replay(recording=f, bus_options=None, speed=0, bus=bus, stop=threading.Event())
    assert changes == [(key, True), (key, False)]


@pytest.mark.parametrize("target", ["/proc/self/x", "/nonexistent-folder/x.mcap"])
def test_record_refuses_an_unwritable_output_before_opening_a_session(target, monkeypatch):
    """The output file is opened before the bus: no session is opened for a file that cannot be
    written (the unmarked test would fail if one were)."""
    res = CliRunner().invoke(cli, ["record", "-o", target])
    assert res.exit_code == 2 and target in res.output, res.output


def test_a_recording_that_cannot_be_written_is_one_error_not_a_traceback():
    """A full disk (/dev/full) fails the writer thread: the recorder stops writing, keeps
    draining, and close() raises one MrtaRuntimeError saying so (the CLI prints one line)."""
    import os

    from mrta_zenoh.errors import MrtaRuntimeError
    from mrta_zenoh.recording import McapRecorder
    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full here")
    rec = McapRecorder(Path("/dev/full"), flush_every=0.0)
    for i in range(200):
        rec.sample("robot1/odom", "application/octet-stream", bytes(1000), t=i)
    with pytest.raises(MrtaRuntimeError, match="No space left on device"):
        rec.close()
