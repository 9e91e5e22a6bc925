"""The real bus: eclipse-zenoh. The only module of the project that imports `zenoh`.

Traps handled here (docs/zenoh.md): every entity is undeclared and the session closed in
close(), so no callback thread keeps the interpreter from exiting; publishers use
CongestionControl.BLOCK, because DROP loses state under bursts — except lossy streams (sensor
data, motivations, the clock), which use DROP so that a stopped subscriber cannot stall them; Python references to tokens and
subscribers are kept for as long as they are meant to live.

A process's own samples reach its own subscriptions in-process (ROS 2's intra-process
delivery): the bus's publishers send to remote sessions only (`Locality.REMOTE`), and publish()
hands the sample to the matching subscriptions of this bus itself, synchronously, before it
returns — as InProcBus does, which every unit test runs on. Zenoh would hand them over on a
callback thread instead: a thread hop, a wrapper object and a decode per sample (a patrol agent
hears its own motivation feed 30 times a simulated second; with 100 agents on 2 cores the agents
took 1.60 cores per simulated second instead of 1.65), and an order against the process's
other work that would depend on scheduling.

Samples from other processes come through one native subscriber per key expression, fanned
out to every subscription of the bus on it and decoded once for them all (`_Fan`): an agent
host's robots subscribe alike, and they are many.
"""

from __future__ import annotations

import json
import logging
import threading
from typing import Any, Callable, Iterable, Sequence

import zenoh

from .. import codec
from ..errors import ConfigError, MrtaRuntimeError
from ..keys import matches
from ..lifecycle import Closing, wait_for_stop
from .base import Batch, Bus, LivelinessWatch, Sample, Subscription, Token
from .options import BusOptions, session_configs
from ..messages import GenericMessage, Message


log = logging.getLogger("mrta.bus")
_encode = codec.encode_struct
zenoh.init_log_from_env_or("error")


def _zenoh_config(cfg: dict[str, Any]) -> "zenoh.Config":
    conf = zenoh.Config()
    for key, value in cfg.items():
        try:
            conf.insert_json5(key, json.dumps(value))
        except zenoh.ZError as exc:
            raise ConfigError(f"invalid Zenoh configuration for {key!r}: {exc}") from None
    return conf


def open_session(opts: BusOptions) -> "zenoh.Session":
    configs = session_configs(opts)
    last: Exception | None = None
    for i, cfg in enumerate(configs):
        conf = _zenoh_config(cfg)
        try:
            return zenoh.open(conf)
        except zenoh.ZError as exc:
            last = exc
            text = str(exc)
            if "Address already in use" in text and i + 1 < len(configs):
                continue  # rendezvous taken: join it instead
            if "Address already in use" in text:
                raise MrtaRuntimeError(f"cannot listen: address already in use ({_first_line(text)})") from None
            if "endpoint" in text.lower() or "locator" in text.lower():
                raise ConfigError(f"Zenoh rejected an endpoint: {_first_line(text)}") from None
            raise MrtaRuntimeError(f"cannot open a Zenoh session: {_first_line(text)}") from None
    raise MrtaRuntimeError(f"cannot open a Zenoh session: {last}")


def _first_line(text: str) -> str:
    return text.split(" at /", 1)[0].strip()


class ZenohBus(Bus):
    def __init__(self, options: BusOptions | None = None):
        options = options or BusOptions()
        super().__init__(options.namespace)
        self.options = options
        self.session = open_session(options)
        self._publishers: dict[str, Any] = {}
        self._pub_lock = threading.Lock()
        self._encodings: dict[str, Any] = {}
        self._declared_encoding: dict[str, str | None] = {}  # key → its publisher's default
        self._typed: dict[str, tuple] = {}
        self._attached: list = []  # attached publishers and subscribers (ROS 2)
        # key → this bus's subscriptions matching it (intra-process delivery), emptied when a
        # subscription comes or goes; `_generation` keeps a look that raced one from sticking
        self._own: dict[str, tuple[Subscription, ...]] = {}
        self._own_lock = threading.Lock()
        self._generation = 0
        self._fans: dict[str, _Fan] = {}  # key expression → its one native subscriber's fan

    @property
    def zid(self) -> str:
        return str(self.session.zid())

    def publish(self, key: str, msg: Message | GenericMessage, lossy: bool = False) -> None:
        # Hot path: one dict lookup gives publisher and encoding (a key nearly always
        # carries one type; a different type just rebuilds the entry).
        entry = self._typed.get(key)
        if entry is None or entry[0] is not type(msg):
            if type(msg) is GenericMessage:
                return super().publish(key, msg, lossy)
            entry = (type(msg), self._publisher(key, lossy),
                     self._encoding(codec.encoding_for(msg.TYPE_NAME)))
            self._typed[key] = entry
        _, pub, enc = entry
        payload = _encode(msg)
        pub.put(payload, encoding=enc)
        counts = self._counts
        if counts is not None and not key.startswith("@"):  # lockstep's own keys: not counted
            counts.sent[key] += 1
        local = self._own_subscriptions(key)
        if local:
            self._hand_over(local, key, codec.encoding_for(msg.TYPE_NAME), payload)

    def publish_raw(self, key: str, encoding: str, payload: bytes, lossy: bool = False) -> None:
        self._publisher(key, lossy).put(payload, encoding=self._encoding(encoding))
        counts = self._counts
        if counts is not None and not key.startswith("@"):
            counts.sent[key] += 1
        local = self._own_subscriptions(key)
        if local:
            self._hand_over(local, key, encoding, payload)

    def _own_subscriptions(self, key: str) -> tuple[Subscription, ...]:
        """This bus's subscriptions matching `key` (remembered until subscriptions change)."""
        local = self._own.get(key)
        if local is not None:
            return local
        with self._own_lock:
            generation = self._generation
            subs = list(self._subs)
        local = tuple(s for s in subs if not s._closed and matches(s.key_expr, key))
        with self._own_lock:
            if generation == self._generation:
                if len(self._own) >= 4 * 4096:  # bounded: keys a process publishes are few
                    self._own.clear()
                self._own[key] = local
        return local

    def _hand_over(self, subs: tuple[Subscription, ...], key: str, encoding: str,
                   payload: bytes) -> None:
        """The sample to this bus's own subscriptions, each as if it came from the network
        (type-checked, counted, its handler or queue) but decoded once for all of them: in an
        agent host K robots hear every teammate's message, and decoding it K times was most
        of what hearing cost (issue 47: 100 robots' `Bids`, each decoded 100 times). Messages
        are frozen, so the robots sharing one cannot tell it from a copy of their own
        (tests/process/test_zenoh_intraprocess.py). What a subscription's error or counting hook raises is
        logged and counted, as Zenoh does on its callback thread: it must neither reach the
        publisher nor keep the sample from the other subscriptions."""
        once: list = [None]
        for sub in subs:
            try:
                sub._dispatch(key, encoding, payload, once)
            except Exception:
                self.stats.add("handler_errors")
                log.exception("delivering %s to this process's subscription %s raised", key,
                              sub.key_expr)

    def _subscriptions_changed(self) -> None:
        with self._own_lock:
            self._generation += 1
            self._own.clear()

    def declare_batch(self, keys: Sequence[str], encodings: Sequence[str],
                      lossy: bool = False) -> Batch:
        return _ZenohBatch(self, keys, encodings, lossy)

    def _publisher(self, key: str, lossy: bool = False, encoding: str | None = None) -> Any:
        """The key's publisher, declared on first use. `encoding`: the default its puts carry
        when they name none (a batch's puts then skip the argument, ≈ 0.1 µs each); a put that
        names one overrides it, so a key published both ways stays correct."""
        pub = self._publishers.get(key)
        if pub is None:
            with self._pub_lock:
                pub = self._publishers.get(key)
                if pub is None:
                    pub = self.session.declare_publisher(
                        self._wire(key), congestion_control=zenoh.CongestionControl.DROP
                        if lossy else zenoh.CongestionControl.BLOCK,
                        encoding=self._encoding(encoding) if encoding is not None else None,
                        allowed_destination=zenoh.Locality.REMOTE)  # own: publish() hands over
                    self._publishers[key] = pub
                    self._declared_encoding[key] = encoding
        return pub

    def _encoding(self, encoding: str) -> Any:
        enc = self._encodings.get(encoding)
        if enc is None:
            enc = self._encodings[encoding] = zenoh.Encoding(encoding)
        return enc

    def _declare(self, sub: Subscription) -> None:
        """One native Zenoh subscriber per key expression, shared by every subscription of
        this bus on it (a `_Fan`): in an agent host K robots subscribe to the same teammates'
        keys, and a native subscriber each made Zenoh copy, and this bus decode, every remote
        sample K times (issue 47). A subscription joining a fan hears from its next sample on,
        as a native subscriber would once declared."""
        ns = self.namespace
        cut = len(ns) + 1 if ns else 0
        with self._own_lock:  # never held across a call into Zenoh (its threads call us)
            fan = self._fans.get(sub.key_expr)
            new = fan is None
            if new:
                fan = self._fans[sub.key_expr] = _Fan(self, cut)
            fan.join(sub)
        sub._native = fan
        if new:
            native = self.session.declare_subscriber(self._wire(sub.key_expr), fan.on_sample)
            with self._own_lock:
                if fan.state[0]:
                    fan.native, native = native, None
            if native is not None:  # every subscription of the fan closed meanwhile
                native.undeclare()
        self._subs.append(sub)
        self._subscriptions_changed()

    def _receiver(self, sub: Subscription, cut: int) -> Callable:
        """What a native subscriber's callback calls for `sub` when it is the only one."""
        if sub.direct:
            return self._direct_receiver(sub, cut)
        dispatch = sub._dispatch

        def on_sample(s: "zenoh.Sample") -> None:
            dispatch(str(s.key_expr)[cut:], str(s.encoding), s.payload.to_bytes())
        return on_sample

    @staticmethod
    def _direct_receiver(sub: Subscription, cut: int):
        """The receive hot path, inlined: decode and call the handler on Zenoh's thread.

        Same behaviour as Subscription._dispatch + _deliver; it only skips re-reading the
        encoding string while samples keep the same encoding (comparing Encoding objects costs
        half of converting one to a string), which is what a subscription nearly always sees,
        and calls msgspec's decoder for a known type directly."""
        handler, make, limit, bus = sub.handler, Sample, codec.MAX_PAYLOAD_BYTES, sub.bus
        errors, translate = codec.DECODE_ERRORS, codec.translate
        # the last Encoding object, its type name, generic decode, and msgspec's typed decode
        last: tuple = (None, None, None, None)

        def on_sample(s: "zenoh.Sample") -> None:
            nonlocal last
            if sub._closed:
                return
            key = str(s.key_expr)[cut:]
            enc = s.encoding
            seen, type_name, decode, raw = last
            if enc != seen:
                entry = sub._decoder(key, str(enc))
                if entry is None:
                    return
                type_name, decode = entry
                raw = codec.typed_decoder(codec.encoding_for(type_name))[1]
                last = (enc, type_name, decode, raw)
            payload = s.payload.to_bytes()
            try:
                if raw is not None and len(payload) <= limit:
                    msg = raw(payload)
                else:
                    msg = decode(payload)
            except codec.DecodeError as exc:
                sub._malformed(key, exc)
                return
            except errors as exc:
                sub._malformed(key, translate(exc, type_name))
                return
            sub.received += 1
            try:
                handler(make(key, type_name, msg, payload))
            except Exception:  # a user's handler must never kill the network thread
                bus.stats.add("handler_errors")
                log.exception("handler for %s raised", sub.key_expr)
            tally = sub._tally
            if tally is not None:  # after the handler: "received" means "taken into account"
                tally.counts[key] += 1
                tally.counted()

        return on_sample

    def _undeclare(self, sub: Subscription) -> None:
        fan, sub._native, native = sub._native, None, None
        if fan is not None:
            with self._own_lock:
                if fan.leave(sub):  # its last subscription: the native subscriber goes
                    native, fan.native = fan.native, None
                    if self._fans.get(sub.key_expr) is fan:
                        del self._fans[sub.key_expr]
        if native is not None:
            native.undeclare()
        self._subscriptions_changed()

    def _declare_token(self, tok: Token) -> None:
        tok._native = self.session.liveliness().declare_token(self._wire(tok.key))
        self._tokens.append(tok)

    def _undeclare_token(self, tok: Token) -> None:
        if tok._native is not None:
            tok._native.undeclare()
            tok._native = None

    def _declare_watch(self, w: LivelinessWatch, history: bool) -> None:
        local = self._local

        def on_sample(s: "zenoh.Sample") -> None:
            w._event(local(str(s.key_expr)), s.kind == zenoh.SampleKind.PUT)

        w._native = self.session.liveliness().declare_subscriber(
            self._wire(w.key_expr), on_sample, history=history
        )
        self._watches.append(w)

    def _undeclare_watch(self, w: LivelinessWatch) -> None:
        if w._native is not None:
            w._native.undeclare()
            w._native = None

    def _declare_queryable(self, key: str,
                           answer: Callable[[], list[tuple[str, bytes]]]) -> "Closable":
        """A queryable replying on its own concrete key (docs/zenoh.md, trap 7), closed before the
        session; the query is dropped when the callback returns, so the asker's get ends."""
        wire, stats, encoding = self._wire(key), self.stats, self._encoding

        def on_query(query: "zenoh.Query") -> None:
            try:
                for enc, payload in answer():
                    query.reply(wire, payload, encoding=encoding(enc))
            except Exception:  # never the network thread's end
                stats.add("handler_errors")
                log.exception("answering a query on %s raised", key)

        q = Closable(self.session.declare_queryable(wire, on_query))
        self._attached.append(q)
        return q

    def _query(self, key_expr: str, timeout: float) -> Iterable[tuple[str, str, bytes]]:
        """Every reply, not consolidated: Zenoh's default keeps the latest reply per key, and a
        queryable answers with many on its one key (a history)."""
        for reply in self.session.get(self._wire(key_expr), timeout=timeout,
                                      consolidation=zenoh.ConsolidationMode.NONE):
            s = reply.ok
            if s is not None:
                yield self._local(str(s.key_expr)), str(s.encoding), s.payload.to_bytes()

    # ------------------------------------------------------------ samples with attachments
    # What ROS 2 over rmw_zenoh needs (mrta_zenoh.ros2): absolute keys (no namespace), raw
    # payloads, and the per-sample attachment rmw_zenoh requires. Kept here so that this stays
    # the only module importing zenoh.
    def declare_attached_publisher(self, key: str, *, lossy: bool,
                                   declare: Callable[..., Any] | None = None
                                   ) -> "AttachedPublisher":
        """A CDR publisher on `key` as given, closed before the session. `declare(key,
        congestion_control=…)` makes it (default: a plain one; ROS 2 topics with history use
        zenoh-ext's AdvancedPublisher, mrta_zenoh/ros2/node.py)."""
        declare = declare or self.session.declare_publisher
        pub = AttachedPublisher(declare(key, congestion_control=zenoh.CongestionControl.DROP
                                        if lossy else zenoh.CongestionControl.BLOCK),
                                self._encoding("application/cdr"))
        self._attached.append(pub)
        return pub

    def subscribe_attached(self, key_expr: str,
                           handler: Callable[[str, bytes, bytes | None], None],
                           declare: Callable[[str, Callable], Any] | None = None
                           ) -> "Closable":
        """handler(key, payload, attachment or None), on Zenoh's thread; an exception it raises
        is counted (`handler_errors`) and logged, never kills the network thread. `declare(key,
        callback)` makes the subscriber (default: a plain one; ROS 2 topics use zenoh-ext's
        AdvancedSubscriber, mrta_zenoh/ros2/node.py)."""
        stats = self.stats

        def on_sample(s: "zenoh.Sample") -> None:
            att = s.attachment
            try:
                handler(str(s.key_expr), s.payload.to_bytes(),
                        att.to_bytes() if att is not None else None)
            except Exception:
                stats.add("handler_errors")
                log.exception("handler for %s raised", key_expr)

        declare = declare or self.session.declare_subscriber
        sub = Closable(declare(key_expr, on_sample))
        self._attached.append(sub)
        return sub

    def declare_absolute_token(self, key: str) -> "Closable":
        """A liveliness token on `key` as given (no namespace): ROS 2's `@ros2_lv/…`."""
        tok = Closable(self.session.liveliness().declare_token(key))
        self._attached.append(tok)
        return tok

    def watch_absolute(self, key_expr: str, on_change: Callable[[str, bool], None]) -> "Closable":
        """Liveliness of `key_expr` as given (no namespace), current tokens first."""
        stats = self.stats

        def on_sample(s: "zenoh.Sample") -> None:
            try:
                on_change(str(s.key_expr), s.kind == zenoh.SampleKind.PUT)
            except Exception:
                stats.add("handler_errors")
                log.exception("liveliness handler for %s raised", key_expr)

        watch = Closable(self.session.liveliness().declare_subscriber(key_expr, on_sample,
                                                                      history=True))
        self._attached.append(watch)
        return watch

    def watch_router_link(self, on_change: Callable[[bool], None]) -> "Closable":
        """This session's transports to routers, opening and closing (Bus.watch_router_link)."""
        stats = self.stats

        def on_event(ev: "zenoh.TransportEvent") -> None:
            if ev.transport.whatami != zenoh.WhatAmI.ROUTER:
                return
            try:
                on_change(ev.kind == zenoh.SampleKind.PUT)
            except Exception:
                stats.add("handler_errors")
                log.exception("router link handler raised")

        watch = Closable(self.session.info.declare_transport_events_listener(on_event,
                                                                             history=True))
        self._attached.append(watch)
        return watch

    def _close_impl(self) -> None:
        for item in self._attached:
            item.close()
        self._attached.clear()
        for pub in self._publishers.values():
            pub.undeclare()
        self._publishers.clear()
        self._declared_encoding.clear()
        self._typed.clear()
        self.session.close()


class _Fan:
    """One native subscriber's samples handed to the bus's subscriptions on its key expression.
    One subscription: its own receiver (the inlined hot path). Several: the sample's key,
    encoding and bytes are read once and `_hand_over` decodes it once for all of them, each
    still filtering by type and counting it and its malformed samples itself, as own samples
    are. Its state is one tuple, replaced whole, for the network thread to read without a lock."""

    __slots__ = ("bus", "cut", "state", "native")

    def __init__(self, bus: ZenohBus, cut: int):
        self.bus, self.cut = bus, cut
        # (subscriptions, the receiver when there is exactly one, else None)
        self.state: tuple[tuple[Subscription, ...], Callable | None] = ((), None)
        self.native: Any = None

    def join(self, sub: Subscription) -> None:
        self._become(self.state[0] + (sub,))

    def leave(self, sub: Subscription) -> bool:
        """True when `sub` was its last subscription."""
        self._become(tuple(s for s in self.state[0] if s is not sub))
        return not self.state[0]

    def _become(self, subs: tuple[Subscription, ...]) -> None:
        self.state = (subs, self.bus._receiver(subs[0], self.cut) if len(subs) == 1 else None)

    def on_sample(self, s: "zenoh.Sample") -> None:
        subs, alone = self.state
        if alone is not None:
            alone(s)
        elif subs:
            self.bus._hand_over(subs, str(s.key_expr)[self.cut:], str(s.encoding),
                                s.payload.to_bytes())


class _ZenohBatch(Batch):
    """Declared publishers, one per key, each with its key's encoding as default: a sample
    costs one put, as in raw zenoh-python."""

    def __init__(self, bus: ZenohBus, keys: Sequence[str], encodings: Sequence[str],
                 lossy: bool):
        super().__init__(bus, keys, encodings, lossy)
        pubs = [bus._publisher(k, lossy, e) for k, e in zip(self.keys, self.encodings)]
        # keys whose publisher was declared earlier with another default: name it per put
        self._plain = all(bus._declared_encoding.get(k) == e
                          for k, e in zip(self.keys, self.encodings))
        self._puts = [p.put for p in pubs]
        self._encs = [bus._encoding(e) for e in self.encodings]
        self._counted_keys = [k for k in self.keys if not k.startswith("@")]
        self._own: tuple[int, list] = (-1, [])  # (generation, [(row, own subscriptions)])

    def publish(self, payloads: Sequence[bytes], rows: Sequence[int] | None = None) -> None:
        self._check(payloads, rows)
        if rows is not None:
            self._publish_rows(payloads, rows)
            return
        if self._plain:
            for put, payload in zip(self._puts, payloads):
                put(payload)
        else:
            for put, enc, payload in zip(self._puts, self._encs, payloads):
                put(payload, encoding=enc)
        counts = self.bus._counts
        if counts is not None:
            counts.sent.update(self._counted_keys)
        self._hand_over(payloads, None)

    def _hand_over(self, payloads: Sequence[bytes], rows: Sequence[int] | None) -> None:
        """The rows sent (all: None) to the bus's own subscriptions matching their keys."""
        bus = self.bus
        generation, local = self._own
        if generation != bus._generation:
            generation = bus._generation
            local = [(i, t) for i, t in enumerate(map(bus._own_subscriptions, self.keys)) if t]
            self._own = (generation, local)
        if not local:
            return
        wanted = None if rows is None else set(rows)
        for i, subs in local:
            if wanted is None or i in wanted:
                bus._hand_over(subs, self.keys[i], self.encodings[i], payloads[i])

    def _publish_rows(self, payloads: Sequence[bytes], rows: Sequence[int]) -> None:
        puts, encs = self._puts, self._encs
        if self._plain:
            for i in rows:
                puts[i](payloads[i])
        else:
            for i in rows:
                puts[i](payloads[i], encoding=encs[i])
        counts = self.bus._counts
        if counts is not None:
            keys = self.keys
            counts.sent.update([keys[i] for i in rows if not keys[i].startswith("@")])
        self._hand_over(payloads, rows)


class Closable(Closing):
    """A declared Zenoh entity, undeclared once by close() — or on leaving a `with` block, like
    every other handle the bus gives out (AttachedPublisher included)."""

    def __init__(self, native: Any):
        self._native = native

    def close(self) -> None:
        if self._native is not None:
            self._native.undeclare()
            self._native = None


class AttachedPublisher(Closable):
    def __init__(self, native: Any, encoding: Any):
        super().__init__(native)
        self._encoding = encoding

    def put(self, payload: bytes, attachment: bytes) -> None:
        if self._native is not None:
            self._native.put(payload, encoding=self._encoding, attachment=attachment)


def run_router(options: BusOptions, stop: threading.Event) -> str:
    """Run a Zenoh router (router mode of the same library) until `stop` is set."""
    session = open_session(options)
    zid = str(session.zid())
    try:
        wait_for_stop(stop)  # in slices: a signal taken by a Zenoh thread is still seen
    finally:
        session.close()
    return zid
