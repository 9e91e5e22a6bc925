"""The live Foxglove server (supervisor/live/foxglove_server.py), in-process on loopback: both
generations of clients connect, a late subscriber gets the latest message of every
channel (38.3), and a client that does not read costs only itself (42.5)."""

from __future__ import annotations

import asyncio
import json
import struct

import pytest
import websockets

from mrta_supervisor.live.foxglove_server import SUB_QUEUE, FoxgloveServer

SCHEMA = ("x_msgs/Alarm", "jsonschema",
          json.dumps({"type": "object", "properties": {"n": {"type": "integer"}}}).encode())


async def hello(server: FoxgloveServer, protocol: str):
    """Connect offering only `protocol`; (socket, serverInfo, {topic: channel}) once every
    channel the server has advertised so far is known to the client."""
    ws = await websockets.connect(server.url, subprotocols=[protocol], max_size=None,
                                  close_timeout=1)
    info = json.loads(await asyncio.wait_for(ws.recv(), 10))
    expected, channels = set(server.by_topic), {}
    while not expected <= set(channels):
        o = json.loads(await asyncio.wait_for(ws.recv(), 10))
        if o["op"] == "advertise":
            channels.update({c["topic"]: c for c in o["channels"]})
    return ws, info, channels


async def subscribe(ws, sub: int, channel: dict, server: FoxgloveServer | None = None) -> None:
    """Subscribe; with `server`, return once the server holds the subscription (what a client
    sees only when a message comes)."""
    await ws.send(json.dumps({"op": "subscribe",
                              "subscriptions": [{"id": sub, "channelId": channel["id"]}]}))
    deadline = asyncio.get_running_loop().time() + 10
    while server is not None and sub not in _client_of(server, ws).subs:
        assert asyncio.get_running_loop().time() < deadline, "the subscription never arrived"
        await asyncio.sleep(0.002)


async def next_data(ws, timeout: float = 10.0) -> tuple[int, int, bytes]:
    """(subscription id, timestamp, payload) of the next message data."""
    while True:
        msg = await asyncio.wait_for(ws.recv(), timeout)
        if isinstance(msg, bytes):
            assert msg[0] == 1
            sub, t = struct.unpack_from("<IQ", msg, 1)
            return sub, t, msg[13:]


@pytest.mark.parametrize("protocol", ["foxglove.websocket.v1", "foxglove.sdk.v1"])
def test_each_client_generation_connects_and_gets_the_same_channels_and_messages(protocol):
    """Foxglove Studio 1.x and Lichtblick before December 2025 offer only
    foxglove.websocket.v1 (foxglove-sdk's server answered them HTTP 400); newer ones
    foxglove.sdk.v1. One port, the same advertisement, the same bytes."""
    with FoxgloveServer("127.0.0.1", 0) as server:
        known = server.advertise("/supervisor/alarms", SCHEMA, "json")
        server.advertise("/world", ("foxglove.SceneUpdate", "protobuf", b"\x0a\x01x"), "protobuf")

        async def client():
            ws, info, channels = await hello(server, protocol)
            async with ws:
                assert ws.subprotocol == protocol
                assert info["op"] == "serverInfo" and info["name"] == "mrta-zenoh"
                assert set(channels) == {"/supervisor/alarms", "/world"}
                alarms = channels["/supervisor/alarms"]
                assert (alarms["encoding"], alarms["schemaName"], alarms["schemaEncoding"]) == (
                    "json", "x_msgs/Alarm", "jsonschema")
                assert json.loads(alarms["schema"])["properties"] == {"n": {"type": "integer"}}
                assert channels["/world"]["schema"] == "CgF4"  # base64, as the protocol says
                await subscribe(ws, 3, alarms, server)
                server.log(known, b'{"n": 1}', 42)
                return await next_data(ws)

        assert asyncio.run(client()) == (3, 42, b'{"n": 1}')


def test_a_client_offering_neither_name_is_refused():
    with FoxgloveServer("127.0.0.1", 0) as server:
        async def client():
            await websockets.connect(server.url, subprotocols=["something.else"])

        with pytest.raises(websockets.exceptions.InvalidHandshake):
            asyncio.run(client())


def test_a_late_subscriber_gets_the_latest_message_of_each_channel_at_once():
    """A channel is advertised with its first message, which therefore went out before anyone
    could subscribe: latched, the subscriber gets it (one alarm of one, not zero)."""
    with FoxgloveServer("127.0.0.1", 0) as server:
        alarms = server.advertise("/supervisor/alarms", SCHEMA, "json")
        report = server.advertise("robot1/patrol/report", SCHEMA, "json")
        server.log(alarms, b'{"n": 1}', 10)
        server.log(report, b'{"n": 5}', 11)
        server.log(report, b'{"n": 6}', 12)

        async def client():
            ws, _, channels = await hello(server, "foxglove.websocket.v1")
            async with ws:
                await subscribe(ws, 1, channels["/supervisor/alarms"])
                await subscribe(ws, 2, channels["robot1/patrol/report"])
                got = {await next_data(ws), await next_data(ws)}
                server.log(alarms, b'{"n": 2}', 20)
                got.add(await next_data(ws))
                return got

        assert asyncio.run(client()) == {(1, 10, b'{"n": 1}'), (2, 12, b'{"n": 6}'),
                                         (1, 20, b'{"n": 2}')}


def test_a_flood_neither_disconnects_a_reading_client_nor_grows_a_stalled_ones_queue():
    """10,000 messages on a flooded channel: a client that never reads keeps at most SUB_QUEUE
    of them queued; a reading client stays connected, gets the newest of the flood, and the
    alarm sent after it, on its channel's own turn."""
    with FoxgloveServer("127.0.0.1", 0) as server:
        flood = server.advertise("robot9999/sonar", SCHEMA, "json")
        alarms = server.advertise("/supervisor/alarms", SCHEMA, "json")

        async def client():
            stalled, _, channels = await hello(server, "foxglove.sdk.v1")
            await subscribe(stalled, 1, channels["robot9999/sonar"], server)
            ws, _, _ = await hello(server, "foxglove.websocket.v1")
            await subscribe(ws, 1, channels["robot9999/sonar"], server)
            await subscribe(ws, 2, channels["/supervisor/alarms"], server)
            pad = b" " * 200
            loop = asyncio.get_running_loop()

            def burst():
                for n in range(10_000):
                    server.log(flood, b'{"n": %d}' % n + pad, n)
                server.log(alarms, b'{"n": -1}', 10_000)
            await loop.run_in_executor(None, burst)
            seen, last = set(), None
            while len(seen) < 2 or last != 9_999:
                sub, t, data = await next_data(ws)
                seen.add(sub)
                if sub == 1:
                    last = t
            queued = max(len(q) for q in _client_of(server, stalled).pending.values())
            assert ws.state.name == "OPEN"
            await ws.close()
            stalled.close_timeout = 0  # it reads nothing, so not the server's close either
            await stalled.close()
            return queued

        assert asyncio.run(client()) <= SUB_QUEUE


def _client_of(server, ws):
    """The server's Client for a client socket (matched by the client's local port)."""
    port = ws.local_address[1]
    return next(c for c in server.clients if c.ws.remote_address[1] == port)


def test_what_is_not_the_protocol_is_counted_and_the_connection_kept():
    with FoxgloveServer("127.0.0.1", 0) as server:
        alarms = server.advertise("/supervisor/alarms", SCHEMA, "json")

        async def client():
            ws, _, channels = await hello(server, "foxglove.websocket.v1")
            async with ws:
                for junk in ("not json", "[1, 2]", json.dumps({"op": "publish"}),
                             json.dumps({"op": "subscribe", "subscriptions": [
                                 {"id": "x", "channelId": 999}]})):
                    await ws.send(junk)
                await ws.send(b"\x01\x02")
                await subscribe(ws, 4, channels["/supervisor/alarms"], server)
                server.log(alarms, b'{"n": 3}', 7)
                return await next_data(ws)

        assert asyncio.run(client()) == (4, 7, b'{"n": 3}')
        assert server.refused == 5
