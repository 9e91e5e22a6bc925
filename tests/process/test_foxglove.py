"""What Foxglove / Lichtblick get: a recording whose every channel has a schema they decode,
the scene and supervisor channels, in simulated time whatever the run's speed, a live WebSocket
stream, and a replay of the bus."""

import asyncio
import json
import statistics
import struct
import time
from collections import defaultdict

import jsonschema
import pytest
from mcap.reader import make_reader

from mrta_zenoh.keys import LIVELINESS_PREFIX
from mrta_zenoh.recording import read_recording
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.mission.plots import TimeBase, replay
from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """One short demo run (robot2 killed at 18 s) and its recording."""
    from tests.harness.helpers import Children
    children = Children()
    out = tmp_path_factory.mktemp("fox") / "run"
    try:
        # ≈ 5 s on an idle machine; set up within the first test's 180 s, its body after
        children.demo(out, "--duration", "30", "--fail", "robot2@18").summary(120)
    finally:
        children.stop_all()
    return out


@pytest.mark.slow
def test_every_channel_has_a_schema_foxglove_decodes_and_every_json_message_fits_it(recorded):
    seen, schemas = {}, {}
    with open(recorded / "run.mcap", "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            assert schema is not None and schema.encoding in ("jsonschema", "protobuf"), channel.topic
            assert channel.message_encoding in ("json", "protobuf"), channel.topic
            seen.setdefault(channel.topic, []).append(message.data)
            schemas[channel.topic] = schema
    for topic, datas in seen.items():
        s = schemas[topic]
        if s.encoding == "jsonschema":
            validator = jsonschema.Draft202012Validator(json.loads(s.data))
            for data in datas[:50]:
                validator.validate(json.loads(data))
    assert schemas["/world"].name == "foxglove.SceneUpdate"
    assert schemas["/supervisor/alarms"].name == "foxglove.Log"
    assert schemas["robot1/alliance/motivation/wander"].name == "alliance_msgs/Motivation"
    for robot in ("robot1", "robot2", "robot3"):
        assert any(robot.encode() in d for d in seen["/world"])        # an entity per robot
        assert f"/robots/{robot}/pose" in seen and f"/robots/{robot}/task" in seen
    assert any(b"communication_lost robot2" in d for d in seen["/supervisor/alarms"])
    tasks = [json.loads(d) for d in seen["/robots/robot2/task"]]
    assert {"state": "busy", "task": "border_protection",
            "activity": "border_protection"} in tasks
    assert tasks[-1]["state"] == tasks[-1]["activity"] == "offline"


@pytest.mark.slow
def test_a_speed_0_recording_is_in_simulated_time_with_frames_per_simulated_second(recorded):
    """The 30 s mission ran in a few wall seconds; its file spans the 30 simulated seconds, so
    Foxglove plays it at mission speed; every channel's log times are in order; /world and the
    poses at 5 Hz, the supervisor at 2 Hz of simulated time; no schema-less JSON channel."""
    times, schemas = defaultdict(list), {}
    with open(recorded / "run.mcap", "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            times[channel.topic].append(message.log_time)
            schemas[channel.topic] = schema
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert meta["mrta"] == {"log_time": "simulated"}
    every = [t for ts in times.values() for t in ts]
    span = (max(every) - min(every)) / 1e9
    assert abs(span - 30.0) <= 1.0, span
    for topic, ts in times.items():
        assert ts == sorted(ts), f"{topic}: log times go back"
        s = schemas[topic]
        if s.encoding == "jsonschema":
            assert set(json.loads(s.data)) - {"title", "type"}, f"{topic}: no real schema"
    # at least one frame per simulated second; mostly every 0.2 s (a recorder starved of CPU
    # skips frames rather than queue them, so the longest gap is not asserted)
    counts = {k: len(times[k]) for k in ("/world", "/robots/robot1/pose", "/supervisor/state",
                                          "/robots/robot1/task")}
    assert min(counts.values()) >= 30, counts
    for topic, period in (("/world", 0.2), ("/supervisor/state", 0.5)):
        ts = [t / 1e9 for t in times[topic]]
        gap = statistics.median(b - a for a, b in zip(ts, ts[1:]))
        assert gap <= period + 0.01, (topic, gap, counts)


@pytest.mark.slow
def test_the_recording_still_replays_the_bus_exactly(recorded):
    """JSON in the file, the wire's msgpack out: typed decoding of every bus record works."""
    from mrta_zenoh import codec
    records = read_recording(recorded / "run.mcap")
    assert len(records) > 5000
    for key, enc, _, payload in records:
        if not key.startswith(LIVELINESS_PREFIX):
            codec.decode(codec.type_from_encoding(enc), payload)


@pytest.mark.slow
def test_replay_feeds_a_live_supervisor_as_the_run_did(recorded, children):
    """The supervisor on the replayed bus (on the replayed clock) sees what the run's summary
    says happened, and the same allocations as the supervisor reading the file."""
    summary = json.loads((recorded / "summary.json").read_text())
    app, arch = resolve_application("patrol")
    records = read_recording(recorded / "run.mcap")
    offline = replay(records, TimeBase(records), app, arch)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", "--rate", "4",
                        name="supervise")
    started = time.monotonic()
    player = children.mrta("replay", recorded / "run.mcap", "--speed", "2", "--clock",
                           name="replay")
    # the run took ≈ 3 wall seconds, but its log times are simulated: 30 s at 2× lasts ≈ 15 s
    live = sup.wait_json(lambda o: o["time"] >= 27.0, 60)  # near the end, the player still on
    got = {r["id"]: (r["state"], r["task"]) for r in live["robots"]}
    assert got == {"robot1": ("busy", "wander"), "robot2": ("offline", None),
                   "robot3": ("busy", "border_protection")}
    assert summary["failure"]["taken_over_by"] == "robot3"
    assert ("communication_lost", "robot2") in {(a["kind"], a["subject"]) for a in live["alarms"]}
    assert player.wait(60) == 0, player.stderr
    assert time.monotonic() - started >= 30 / 2 - 0.5  # paced by the simulated log times
    allocated = {t.subject for t in offline.history.all() if t.kind == "allocation" and t.new}
    assert {"wander->robot1", "border_protection->robot2", "border_protection->robot3"} <= allocated
    # the sequence of changes: robots' states and allocations, as the live supervisor saw them
    # on the replayed bus and as the supervisor reading the file saw them
    live_changes = {}
    for line in sup.stdout:
        try:
            snap = json.loads(line)
        except ValueError:
            continue
        for t in snap["transitions"]:
            live_changes[(t["time"], t["kind"], t["subject"], t["from"], t["to"])] = None
    live_seq = [c[1:] for c in sorted(live_changes) if c[1] in ("robot", "allocation")
                and c[0] <= live["time"]]
    file_seq = [(t.kind, t.subject, t.old, t.new) for t in offline.history.all()
                if t.kind in ("robot", "allocation") and t.time <= live["time"]]
    assert sorted(live_seq) == sorted(file_seq), (live_seq, file_seq)


def test_a_websocket_client_of_either_generation_sees_the_channels_and_scene_updates(
        children, tokens):
    """`mrta view` on its own (no application): a client offering only the old subprotocol
    name (Foxglove Studio 1.x, Lichtblick before December 2025) and one offering only the new
    one (foxglove.sdk.v1) each get the channels and a `/world` frame."""
    import websockets

    port = free_port()
    sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--speed", "2", name="sim")
    tokens.wait("@mrta/clock_source/*", 60, sim)
    view = children.mrta("view", "--port", port, name="view")
    # the WebSocket server's address, logged once it listens (the view declares no token)
    view.wait_stderr(lambda line: f"ws://127.0.0.1:{port}" in line or "Open connection" in line, 60)

    async def client(protocol):
        async with websockets.connect(f"ws://127.0.0.1:{port}", subprotocols=[protocol],
                                      max_size=None) as ws:
            assert ws.subprotocol == protocol
            channels = {}
            while not {"/world", "robot1/sonar"} <= set(channels):
                msg = await asyncio.wait_for(ws.recv(), 30)
                if isinstance(msg, str):
                    o = json.loads(msg)
                    if o.get("op") == "advertise":
                        channels.update({c["topic"]: c for c in o["channels"]})
            world = channels["/world"]
            assert world["schemaName"] == "foxglove.SceneUpdate" and world["encoding"] == "protobuf"
            await ws.send(json.dumps({"op": "subscribe",
                                      "subscriptions": [{"id": 7, "channelId": world["id"]}]}))
            while True:
                msg = await asyncio.wait_for(ws.recv(), 30)
                if isinstance(msg, bytes) and msg[0] == 1:
                    sub_id, = struct.unpack_from("<I", msg, 1)
                    assert sub_id == 7
                    return msg[13:], channels

    for protocol in ("foxglove.websocket.v1", "foxglove.sdk.v1"):
        try:
            payload, channels = asyncio.run(client(protocol))
        except TimeoutError:  # say what the processes said
            raise AssertionError(f"{protocol}: no frame within 30 s; view running: "
                                 f"{view.running()}\nview: {view.tail()}\nsim: {sim.tail()}") \
                from None
        assert b"robot1" in payload and b"walls" in payload, protocol
        assert "robot1/sonar" in channels and channels["robot1/sonar"]["encoding"] == "json"


LOW_RATE = ("/supervisor/alarms", "/robots/robot2/task", "world")


@pytest.mark.slow
def test_a_client_that_subscribes_at_once_gets_what_the_recording_holds(tmp_path, children):
    """`mrta demo --foxglove`: a client connects as soon as the server listens, subscribes to
    every channel advertised (the application's are advertised at start) and reads until the
    run ends. Per low-rate channel (alarms, reports, a robot's task, the world), what it got is
    what the run's recording holds over the same interval — from its first message on, which
    is the channel's first (latched) — in order, not 1 of 2 alarms and 0 of 1 patrol
    reports."""
    import websockets

    port = free_port()
    out = tmp_path / "run"
    demo = children.demo(out, "--duration", "30", "--fail", "robot2@18", "--foxglove", port)

    async def client():
        got: dict[str, list[bytes]] = defaultdict(list)
        for _ in range(1200):  # the server listens once the recorder starts
            try:
                ws = await websockets.connect(f"ws://127.0.0.1:{port}", max_size=None,
                                              subprotocols=["foxglove.websocket.v1"])
                break
            except OSError:
                await asyncio.sleep(0.05)
        else:
            raise AssertionError("the demo's server never listened")
        topics, subscribed = {}, set()
        async with ws:
            try:
                while True:
                    msg = await asyncio.wait_for(ws.recv(), 120)
                    if isinstance(msg, bytes):
                        sub, = struct.unpack_from("<I", msg, 1)
                        got[topics[sub]].append(msg[13:])
                        continue
                    o = json.loads(msg)
                    if o.get("op") != "advertise":
                        continue
                    new = [c for c in o["channels"] if c["id"] not in subscribed]
                    topics.update({c["id"]: c["topic"] for c in new})
                    subscribed.update(c["id"] for c in new)
                    await ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                        {"id": c["id"], "channelId": c["id"]} for c in new]}))
            except websockets.exceptions.ConnectionClosed:
                return got

    got = asyncio.run(client())
    assert demo.wait(120) == 0, demo.stderr[-10:]
    recorded: dict[str, list[bytes]] = defaultdict(list)
    with open(out / "run.mcap", "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=False):
            recorded[channel.topic].append(message.data)
    reports = sorted(t for t in recorded if t.endswith("/patrol/report"))
    assert reports and any(b"communication_lost robot2" in d
                           for d in recorded["/supervisor/alarms"])
    for topic in (*LOW_RATE, *reports):
        live, rec = got[topic], recorded[topic]
        assert live, f"{topic}: nothing live"
        start = rec.index(live[0])
        assert live == rec[start:], (topic, len(live), len(rec), start)
        if topic == "/supervisor/alarms" or topic in reports:
            assert start == 0, (topic, start)  # subscribed at once: none missed


