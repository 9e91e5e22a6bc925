"""A Foxglove WebSocket server every client generation connects to (docs/foxglove.md).

The protocol is Foxglove's WebSocket protocol (github.com/foxglove/ws-protocol): JSON text
messages (`serverInfo`, `advertise`, `unadvertise` to the client; `subscribe`, `unsubscribe`
from it) and binary message data (opcode 1, subscription id u32, timestamp u64 ns, payload),
all little-endian. Its subprotocol was renamed `foxglove.sdk.v1` by foxglove-sdk, whose server
answers any client offering only the old name `foxglove.websocket.v1` with HTTP 400 — every
Foxglove Studio 1.x, every Lichtblick before December 2025, `@foxglove/ws-protocol`'s client.
The two names carry the same protocol (Foxglove's own stance, and Lichtblick's change that
accepted the new name by adding it to a list), so this server accepts both, on one port, with
the same channels and messages.

What it adds over foxglove-sdk's server, each for a measured reason:

* **Latched channels.** The latest message of every channel is kept, and a client that
  subscribes gets it at once, as a ROS user expects of a latched topic: an alarm, a report or
  the world, published once before the client could subscribe, is not lost (a channel is
  advertised on its first message, so its first message always went out before anyone could
  subscribe to it).
* **Channels advertised up front**: the caller declares what it knows will come (the
  application's robots, the architecture's keys, the derived channels) before any message, so
  a layout's panels find their topics as soon as a client connects.
* **A slow client costs only itself.** Each client has, per subscription, a queue of the newest
  SUB_QUEUE messages (older ones are dropped for that client alone) drained round-robin by one
  sender task, so a flood on one channel neither starves another channel nor grows memory, and
  no client is ever disconnected because someone else flooded the bus (foxglove-sdk
  disconnects a client whose backlog overflows).

Threads: `advertise` and `log` are called from any thread (Zenoh's callbacks, the frame loop);
the server runs an asyncio loop on a thread of its own. `log` only appends to per-client queues
under a lock and wakes a client's sender once; nothing here blocks the bus.
"""

from __future__ import annotations

import asyncio
import base64
import collections
import json
import logging
import struct
import threading
from dataclasses import dataclass, field

from websockets.asyncio.server import ServerConnection, serve
from websockets.exceptions import ConnectionClosed

from mrta_zenoh.lifecycle import Closing

log = logging.getLogger("mrta.view")

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")  # the same protocol, two names
SUB_QUEUE = 16  # messages kept per subscription for a client behind (the newest)
MAX_CLIENT_TEXT = 1 << 20  # bytes of one message a client may send (subscribe lists)
MESSAGE_DATA = 1  # binary opcode: server → client message data


@dataclass
class Channel:
    id: int
    topic: str
    encoding: str  # message encoding: json, protobuf
    schema_name: str
    schema_encoding: str  # jsonschema, protobuf
    schema: bytes
    latest: tuple[int, bytes] | None = None  # (timestamp ns, payload), what a new subscriber gets

    def advertisement(self) -> dict:
        text = self.schema.decode() if self.schema_encoding == "jsonschema" \
            else base64.b64encode(self.schema).decode()
        return {"id": self.id, "topic": self.topic, "encoding": self.encoding,
                "schemaName": self.schema_name, "schema": text,
                "schemaEncoding": self.schema_encoding}


@dataclass
class Client:
    """One connection: its subscriptions and what waits to be sent to it."""

    ws: ServerConnection
    wake: asyncio.Event = field(default_factory=asyncio.Event)
    subs: dict[int, int] = field(default_factory=dict)  # subscription id → channel id
    by_channel: dict[int, set[int]] = field(default_factory=dict)  # channel id → subscription ids
    pending: dict[int, collections.deque] = field(default_factory=dict)  # sub id → messages
    ready: collections.OrderedDict = field(default_factory=collections.OrderedDict)  # sub ids
    dropped: int = 0  # messages dropped because this client was behind
    waking: bool = False

    def queue(self, sub: int, item: tuple[int, bytes]) -> bool:
        """Under the server's lock: queue a message; True when the sender must be woken."""
        q = self.pending.setdefault(sub, collections.deque(maxlen=SUB_QUEUE))
        if len(q) == SUB_QUEUE:
            self.dropped += 1
        q.append(item)
        self.ready[sub] = None
        if self.waking:
            return False
        self.waking = True
        return True


class FoxgloveServer(Closing):
    """Serves channels to Foxglove / Lichtblick clients; a context manager (stops on exit)."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765, name: str = "mrta-zenoh"):
        self.host, self.name = host, name
        self._lock = threading.Lock()
        self.channels: dict[int, Channel] = {}
        self.by_topic: dict[str, Channel] = {}
        self.clients: list[Client] = []
        self.refused = 0  # client messages that were not the protocol's
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._stopped: asyncio.Event | None = None
        self._error: BaseException | None = None
        self.port = 0
        self._thread = threading.Thread(target=self._run, args=(port,), name="foxglove-server",
                                        daemon=True)
        self._thread.start()
        self._ready.wait()
        if self._error is not None:
            self._thread.join()
            raise self._error

    # ------------------------------------------------------------------ the caller's side
    def advertise(self, topic: str, schema: tuple[str, str, bytes], encoding: str) -> Channel:
        """The channel of `topic`, advertised to every client on its creation."""
        with self._lock:
            ch = self.by_topic.get(topic)
            if ch is not None:
                return ch
            name, schema_encoding, data = schema
            ch = Channel(len(self.channels) + 1, topic, encoding, name, schema_encoding, data)
            self.channels[ch.id] = ch
            self.by_topic[topic] = ch
            clients = list(self.clients)
        text = json.dumps({"op": "advertise", "channels": [ch.advertisement()]})
        for c in clients:
            self._call(self._send_text, c, text)
        return ch

    def log(self, channel: Channel, data: bytes, t_ns: int) -> None:
        """A message on `channel`: kept as its latest, queued for every subscriber."""
        item = (t_ns, data)
        wake = []
        with self._lock:
            channel.latest = item
            for c in self.clients:
                for sub in c.by_channel.get(channel.id, ()):
                    if c.queue(sub, item):
                        wake.append(c)
        for c in wake:
            self._call(c.wake.set)

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def close(self) -> None:
        if self._stopped is not None and self._thread.is_alive():
            self._call(self._stopped.set)
        self._thread.join(10)

    # ------------------------------------------------------------------ the loop's side
    def _call(self, fn, *args) -> None:
        try:
            self._loop.call_soon_threadsafe(fn, *args)
        except RuntimeError:  # the loop is closed: the server stopped
            pass

    def _run(self, port: int) -> None:
        try:
            self._loop.run_until_complete(self._main(port))
        except BaseException as exc:  # noqa: BLE001 - handed to the constructor's caller
            if not self._ready.is_set():
                self._error = exc
        finally:
            self._ready.set()
            self._loop.close()

    async def _main(self, port: int) -> None:
        self._stopped = asyncio.Event()
        async with serve(self._handle, self.host, port, subprotocols=list(SUBPROTOCOLS),
                         compression=None, max_size=MAX_CLIENT_TEXT) as server:
            self.port = server.sockets[0].getsockname()[1]
            self._ready.set()
            await self._stopped.wait()

    def _send_text(self, client: Client, text: str) -> None:
        asyncio.ensure_future(self._quiet(client.ws.send(text)))

    @staticmethod
    async def _quiet(coro) -> None:
        try:
            await coro
        except ConnectionClosed:
            pass

    async def _handle(self, ws: ServerConnection) -> None:
        client = Client(ws)
        with self._lock:
            self.clients.append(client)
            ads = [ch.advertisement() for ch in self.channels.values()]
        sender = asyncio.ensure_future(self._sender(client))
        try:
            await ws.send(json.dumps({"op": "serverInfo", "name": self.name, "capabilities": [],
                                      "supportedEncodings": [], "metadata": {},
                                      "sessionId": str(id(self))}))
            if ads:
                await ws.send(json.dumps({"op": "advertise", "channels": ads}))
            async for message in ws:
                self._on_client(client, message)
        except ConnectionClosed:
            pass
        finally:
            with self._lock:
                self.clients.remove(client)
            sender.cancel()
            if client.dropped:
                log.info("a Foxglove client behind: %d messages not sent to it", client.dropped)

    def _on_client(self, client: Client, message) -> None:
        """`subscribe` / `unsubscribe`; anything else is counted and ignored (this server
        advertises no capability a client could use to send more)."""
        try:
            op = json.loads(message) if isinstance(message, str) else None
        except ValueError:
            op = None
        if not isinstance(op, dict):
            self.refused += 1
            return
        wake = False
        with self._lock:
            if op.get("op") == "subscribe":
                for s in op.get("subscriptions", ()):
                    sub, ch = s.get("id"), self.channels.get(s.get("channelId"))
                    if not isinstance(sub, int) or ch is None or sub in client.subs:
                        self.refused += 1
                        continue
                    client.subs[sub] = ch.id
                    client.by_channel.setdefault(ch.id, set()).add(sub)
                    if ch.latest is not None:  # latched: the latest message at once
                        wake |= client.queue(sub, ch.latest)
            elif op.get("op") == "unsubscribe":
                for sub in op.get("subscriptionIds", ()):
                    ch = client.subs.pop(sub, None)
                    if ch is not None:
                        client.by_channel[ch].discard(sub)
                        client.pending.pop(sub, None)
                        client.ready.pop(sub, None)
            else:
                self.refused += 1
        if wake:
            client.wake.set()

    async def _sender(self, client: Client) -> None:
        """Round-robin over the subscriptions with something to send, one message each."""
        header = struct.Struct("<BIQ")
        while True:
            await client.wake.wait()
            while True:
                with self._lock:
                    if not client.ready:
                        client.wake.clear()
                        client.waking = False
                        break
                    sub, _ = client.ready.popitem(last=False)
                    q = client.pending.get(sub)
                    if not q:
                        continue
                    t_ns, data = q.popleft()
                    if q:
                        client.ready[sub] = None
                try:
                    await client.ws.send(header.pack(MESSAGE_DATA, sub, max(t_ns, 0)) + data)
                except ConnectionClosed:
                    return
