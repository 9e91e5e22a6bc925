"""The Bus interface and what both implementations share: decoding, queues, bad-sample accounting.

Implementations only move bytes: they hand `(key, encoding, payload)` to `_dispatch` of each
matching subscription. Everything a user relies on — strict decoding, type filters, ROS-like
`queue_size`, counted and rate-limited warnings — lives here once.
"""

from __future__ import annotations

import collections
import logging
import threading
import time
from typing import Any, Callable, Iterable, Iterator, Sequence

import msgspec

from .. import codec
from ..errors import MrtaRuntimeError
from ..keys import validate_key_expr
from ..lifecycle import Closing
from ..messages import GenericMessage, Message
from .counts import Counts

log = logging.getLogger("mrta.bus")


class Sample(msgspec.Struct, frozen=True, gc=False):
    """A decoded sample. A frozen msgspec Struct: immutable, and built in C (a quarter of a
    NamedTuple's cost, which matters once per sample on the receive path)."""

    key: str
    type_name: str
    message: Any
    payload: bytes


class RawSample(msgspec.Struct, frozen=True, gc=False):
    key: str
    encoding: str
    payload: bytes


Handler = Callable[[Sample], None]
ErrorHandler = Callable[[str, Exception], None]


class Stats:
    """Counters per bus; read by tests, `--json` outputs and benchmarks."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.counts: collections.Counter[str] = collections.Counter()

    def add(self, name: str, n: int = 1) -> None:
        with self._lock:
            self.counts[name] += n

    def __getitem__(self, name: str) -> int:
        return self.counts[name]


class _RateLimitedWarning:
    """At most one log line per (kind, key expression) per `period` seconds, with a running count."""

    def __init__(self, period: float = 5.0):
        self.period = period
        self._last: dict[tuple[str, str], float] = {}
        self._lock = threading.Lock()

    def __call__(self, kind: str, where: str, text: str, count: int) -> None:
        now = time.monotonic()
        with self._lock:
            last = self._last.get((kind, where))
            if last is not None and now - last < self.period:
                return
            self._last[(kind, where)] = now
        log.warning("%s (%d so far on %s)", text, count, where)


class Subscription(Closing):
    """A declared interest in a key expression.

    Delivery modes: a handler called on the network thread (keep it tiny), a handler called from
    a worker thread through a bounded queue, or no handler at all and `get()` / iteration.
    A bounded queue keeps the newest `queue_size` samples and drops the oldest, as ROS does.
    """

    def __init__(
        self,
        bus: "Bus",
        key_expr: str,
        handler: Handler | None,
        queue_size: int | None,
        msg_type: type[Message] | None,
        on_error: ErrorHandler | None,
        raw: bool = False,
    ):
        self.bus = bus
        self.key_expr = key_expr
        self.handler = handler
        self.msg_type = msg_type
        self.on_error = on_error
        self.raw = raw
        self._tally = None  # its lockstep counts (Counts.tally), once the bus counts
        self.received = 0
        self.malformed = 0
        self.wrong_type = 0
        self.dropped = 0
        self._closed = False
        self._queue: collections.deque | None = None
        self._cond: threading.Condition | None = None
        self._worker: threading.Thread | None = None
        self._expected_type = msg_type.TYPE_NAME if msg_type is not None else None
        self._decoders: dict[str, tuple] = {}
        if handler is None or queue_size is not None:
            self._queue = collections.deque(maxlen=queue_size or 1000)
            self._cond = threading.Condition()
            if handler is not None:
                self._worker = threading.Thread(
                    target=self._drain, name=f"mrta-sub:{key_expr}", daemon=True
                )
                self._worker.start()
        self._native: Any = None  # the implementation's handle

    # ---- called by the implementation on its receive thread
    def _dispatch(self, key: str, encoding: str, payload: bytes,
                  once: list | None = None) -> None:
        """Decode and deliver one sample. `once`: a one-slot list shared by the subscriptions
        of one process that one sample reaches (`dispatch_once`) — the first to decode it
        leaves there the sample (or why it is malformed) for the others."""
        if self._closed:
            return
        if self.raw:
            self._deliver(RawSample(key, encoding, payload))
            return
        entry = self._decoder(key, encoding)  # its own type filter and counts, every time
        if entry is None:
            return
        done = None if once is None else once[0]
        if done is None:
            type_name, decode = entry
            try:
                done = Sample(key, type_name, decode(payload), payload)
            except codec.DecodeError as exc:
                done = exc
            # a GenericMessage's value is a mutable dict: each subscription gets its own
            if once is not None and not (type(done) is Sample
                                         and type(done.message) is GenericMessage):
                once[0] = done
        if type(done) is Sample:
            self._deliver(done)
        else:
            self._malformed(key, done)

    def _decoder(self, key: str, encoding: str) -> tuple | None:
        """(type name, decode) for an encoding string; None (counted) for a wrong type or a
        foreign encoding. Cached: encodings come from the network, so the cache is bounded."""
        entry = self._decoders.get(encoding)
        if entry is None:
            try:
                entry = codec.decoder_for(encoding)
            except codec.DecodeError as exc:
                self._malformed(key, exc)
                return None
            if len(self._decoders) < 64:
                self._decoders[encoding] = entry
        if self._expected_type is not None and entry[0] != self._expected_type:
            self.wrong_type += 1
            self.bus.stats.add("wrong_type")
            self.bus._warn("wrong_type", self.key_expr,
                           f"sample on {key} is {entry[0]}, expected {self._expected_type}: ignored",
                           self.wrong_type)
            return None
        return entry

    def _malformed(self, key: str, exc: Exception) -> None:
        self.malformed += 1
        self.bus.stats.add("malformed")
        if self.on_error is not None:
            self.on_error(key, exc)
        else:
            self.bus._warn("malformed", self.key_expr, f"dropped malformed sample on {key}: {exc}",
                           self.malformed)

    @property
    def direct(self) -> bool:
        """Typed samples handed straight to a handler on the receive thread (the hot path an
        implementation may inline)."""
        return not self.raw and self._queue is None and self.handler is not None

    def _deliver(self, sample: Any) -> None:
        self.received += 1
        if self._queue is None:
            try:
                self.handler(sample)
            except Exception:  # a user's handler must never kill the network thread
                self.bus.stats.add("handler_errors")
                log.exception("handler for %s raised", self.key_expr)
            tally = self._tally
            if tally is not None:  # after the handler: "received" means "taken into account"
                tally.counts[sample.key] += 1
                tally.counted()
            return
        tally = self._tally
        if tally is not None:
            tally.counts[sample.key] += 1
            tally.counted()
        with self._cond:
            if len(self._queue) == self._queue.maxlen:
                self.dropped += 1
            self._queue.append(sample)
            self._cond.notify()

    def _drain(self) -> None:
        while True:
            with self._cond:
                while not self._queue and not self._closed:
                    self._cond.wait()
                if self._closed:
                    return
                sample = self._queue.popleft()
            try:
                self.handler(sample)
            except Exception:
                self.bus.stats.add("handler_errors")
                log.exception("handler for %s raised", self.key_expr)

    # ---- pull API
    def get(self, timeout: float | None = None) -> Any:
        """The oldest queued sample, or None after `timeout` seconds (or when closed)."""
        if self._queue is None or self._worker is not None:
            raise RuntimeError("get() is for subscriptions declared without a handler")
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._cond:
            while not self._queue:
                if self._closed:
                    return None
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self._cond.wait(remaining if remaining is not None else 0.1)
            return self._queue.popleft()

    def __iter__(self) -> Iterator[Any]:
        while not self._closed:
            s = self.get(timeout=0.1)
            if s is not None:
                yield s

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self._cond is not None:
            with self._cond:
                self._cond.notify_all()
        self.bus._undeclare(self)
        self.bus._forget(self.bus._subs, self)


class Batch:
    """A fixed list of keys whose pre-encoded samples go out together (Bus.declare_batch): a
    simulator sending thousands of sensor samples per period pays neither a message object nor
    a key lookup per sample. This generic one sends through `publish_raw`, sample by sample;
    an implementation may keep declared publishers instead (ZenohBus)."""

    def __init__(self, bus: "Bus", keys: Sequence[str], encodings: Sequence[str], lossy: bool):
        if len(keys) != len(encodings):
            raise ValueError(f"a batch needs one encoding per key: {len(keys)} keys, "
                             f"{len(encodings)} encodings")
        self.bus = bus
        self.keys = list(keys)
        self.encodings = list(encodings)
        self.lossy = lossy

    def publish(self, payloads: Sequence[bytes], rows: Sequence[int] | None = None) -> None:
        """Send payloads[i] on keys[i] with encodings[i], in order; counted as Bus.publish
        counts (lockstep). `rows`: send only those indices (ascending), `payloads` still one
        per key — a simulator sends an event-like sample (a bumper) only when it changed."""
        self._check(payloads, rows)
        raw, lossy = self.bus.publish_raw, self.lossy
        for i in range(len(self.keys)) if rows is None else rows:
            raw(self.keys[i], self.encodings[i], payloads[i], lossy)

    def _check(self, payloads: Sequence[bytes], rows: Sequence[int] | None = None) -> None:
        if len(payloads) != len(self.keys):
            raise ValueError(f"a batch of {len(self.keys)} keys got {len(payloads)} payloads")
        if rows is not None and len(rows) and not 0 <= min(rows) <= max(rows) < len(self.keys):
            raise ValueError(f"rows outside a batch of {len(self.keys)} keys: "
                             f"{min(rows)}..{max(rows)}")
        if self.bus.closed:
            raise MrtaRuntimeError("publishing a batch on a closed bus")


class LivelinessWatch(Closing):
    """Reports tokens appearing and disappearing under a key expression: on_change(key, alive)."""

    def __init__(self, bus: "Bus", key_expr: str, on_change: Callable[[str, bool], None]):
        self.bus = bus
        self.key_expr = key_expr
        self.on_change = on_change
        self._native: Any = None
        self._closed = False

    def _event(self, key: str, alive: bool) -> None:
        if self._closed:
            return
        try:
            self.on_change(key, alive)
        except Exception:
            log.exception("liveliness handler for %s raised", self.key_expr)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.bus._undeclare_watch(self)
            self.bus._forget(self.bus._watches, self)


class Token(Closing):
    def __init__(self, bus: "Bus", key: str):
        self.bus = bus
        self.key = key
        self._native: Any = None
        self._closed = False

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.bus._undeclare_token(self)
            self.bus._forget(self.bus._tokens, self)


class Bus(Closing):
    """Publish typed messages, subscribe by key expression, and track liveliness.

    `namespace` prefixes every key on the wire (like ROS_DOMAIN_ID) and is stripped from the keys
    handed to subscribers, so application code never sees it.
    """

    def __init__(self, namespace: str = ""):
        self.namespace = namespace.strip("/")
        if self.namespace:
            validate_key_expr(self.namespace)
        self.stats = Stats()
        self._warn = _RateLimitedWarning()
        self._subs: list[Subscription] = []
        self._watches: list[LivelinessWatch] = []
        self._tokens: list[Token] = []
        self._lock = threading.Lock()
        self._closed = False
        self._counts: Counts | None = None  # lockstep's (enable_counting), else nothing counted
        self._unclaimed: set[str] = set()   # leave_unclaimed

    # ---- public API
    def publish(self, key: str, msg: Message | GenericMessage, lossy: bool = False) -> None:
        """Send `msg` on `key`. `lossy`: a stream whose next sample supersedes this one (sensor
        data, motivations, the clock) — dropped rather than waited for when a receiver does not
        keep up, like ROS best-effort, so a stopped observer cannot slow the world. Otherwise
        (commands, broadcasts, state) the publisher waits. A key keeps the choice of its first
        publish."""
        type_name = msg.type_name if type(msg) is GenericMessage else msg.TYPE_NAME
        self.publish_raw(key, codec.encoding_for(type_name), codec.encode(msg), lossy)

    def publish_raw(self, key: str, encoding: str, payload: bytes, lossy: bool = False) -> None:
        raise NotImplementedError

    def declare_batch(self, keys: Sequence[str], encodings: Sequence[str],
                      lossy: bool = False) -> Batch:
        """A handle that publishes one pre-encoded payload per key in one call
        (`batch.publish(payloads)`), each exactly as `publish_raw(key, encoding, payload,
        lossy)` would. The payloads must be what `codec.encode` gives for the encoding's type:
        the batch sends bytes, it does not check them."""
        return Batch(self, keys, encodings, lossy)

    def subscribe(
        self,
        key_expr: str,
        handler: Handler | None = None,
        *,
        queue_size: int | None = None,
        msg_type: type[Message] | None = None,
        on_error: ErrorHandler | None = None,
    ) -> Subscription:
        validate_key_expr(key_expr)
        sub = Subscription(self, key_expr, handler, queue_size, msg_type, on_error)
        self._attach_tally(sub)  # counted from its first sample
        self._declare(sub)
        self._attach_tally(sub)  # (if counting was turned on meanwhile)
        return sub

    def subscribe_raw(
        self, key_expr: str, handler: Callable[[RawSample], None] | None = None,
        *, queue_size: int | None = None,
    ) -> Subscription:
        """Undecoded samples (recording, bridges): key, encoding string and payload bytes."""
        validate_key_expr(key_expr)
        sub = Subscription(self, key_expr, handler, queue_size, None, None, raw=True)
        self._declare(sub)
        return sub

    def answer_queries(self, key: str, answer: Callable[[], Sequence[Message]]) -> Closing:
        """Answer every query on `key` (`query`) with the messages `answer()` gives at that
        moment, one reply each, until closed: what a process that joins late asks for what it
        missed (Zenoh's queryable; rmw_zenoh's transient local durability is zenoh-ext's
        publication cache, a queryable too). `answer` runs on the network's thread: it should
        return a copy it already holds. Not counted for lockstep: a reply is history, and no
        lockstep participant's decision reads one."""
        validate_key_expr(key)

        def encoded() -> list[tuple[str, bytes]]:
            return [(codec.encoding_for(m.TYPE_NAME), codec.encode(m)) for m in answer()]
        return self._declare_queryable(key, encoded)

    def query(self, key_expr: str, handler: Handler, *, msg_type: type[Message] | None = None,
              timeout: float) -> int:
        """Ask whoever answers queries on `key_expr` (`answer_queries`), and hand each reply to
        `handler` as a subscription on `key_expr` would a sample (a reply that does not decode,
        or is of another type, is counted and dropped); returns once every answer came or
        `timeout` wall seconds passed, with how many replies were handed over."""
        validate_key_expr(key_expr)
        replies = Subscription(self, key_expr, handler, None, msg_type, None)  # never declared
        for key, encoding, payload in self._query(key_expr, timeout):
            replies._dispatch(key, encoding, payload)
        return replies.received

    def declare_token(self, key: str) -> Token:
        """Announce presence under `key` until closed (or until this process dies)."""
        validate_key_expr(key)
        tok = Token(self, key)
        self._declare_token(tok)
        return tok

    def watch_liveliness(
        self, key_expr: str, on_change: Callable[[str, bool], None], history: bool = True
    ) -> LivelinessWatch:
        """Call on_change(key, True/False) as tokens appear/disappear; history: report current ones."""
        validate_key_expr(key_expr)
        w = LivelinessWatch(self, key_expr, on_change)
        self._declare_watch(w, history)
        return w

    def watch_absolute(self, key_expr: str, on_change: Callable[[str, bool], None]) -> Any:
        """Liveliness of `key_expr` as given, whatever this bus's namespace (ROS 2's
        `@ros2_lv/…`). ZenohBus watches it directly; here, without a namespace, it is the same
        as watch_liveliness."""
        if self.namespace:
            raise MrtaRuntimeError(f"{type(self).__name__} cannot watch {key_expr!r} outside "
                                   f"its namespace {self.namespace!r}")
        return self.watch_liveliness(key_expr, on_change)

    def watch_router_link(self, on_change: Callable[[bool], None]) -> Closing:
        """Call on_change(True/False) as this bus's own link to a Zenoh router opens and closes
        (the current one first). What another process's token going means depends on it: with
        this link down, every remote token goes at once in this process's view, though no other
        process lost anything (supervisor/mission/run_watch.py). A bus with no router link (the
        in-process bus, a peer) never calls it."""
        return _NoWatch()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            subs, watches, tokens = list(self._subs), list(self._watches), list(self._tokens)
        for s in subs:
            s.close()
        for w in watches:
            w.close()
        for t in tokens:
            t.close()
        self._close_impl()

    @property
    def closed(self) -> bool:
        return self._closed

    def enable_counting(self, on_counted: Callable[[], None] | None = None) -> Counts:
        """Count, for lockstep, the samples this bus publishes and those its subscriptions take
        into account, from now on; `on_counted()` after each received sample is counted (on the
        thread that delivered it: keep it tiny). The counts have one owner (a lockstep
        participant, or the simulator's barrier) until it closes them."""
        with self._lock:
            if self._counts is not None:
                raise MrtaRuntimeError("this bus already counts for lockstep: counting has one "
                                       "owner")
            counts = self._counts = Counts(self, on_counted)
            subs = list(self._subs)
        for sub in subs:
            self._attach_tally(sub)
        return counts

    def leave_unclaimed(self, key: str) -> None:
        """Samples on `key` are monitoring for observers (the supervisor, the recorder), which
        no lockstep participant's decisions read: lockstep holds no step for them, so this
        bus does not claim them (Counts.claims; they are still counted as sent). An ALLIANCE
        robot's motivation and sensory feedback per task are such keys — with 100 robots and
        100 tasks, 20,000 of them, five times what a run's key table holds (MAX_KEYS)."""
        self._unclaimed.add(key)

    def _stop_counting(self, counts: Counts) -> None:
        with self._lock:
            if self._counts is not counts:
                return
            self._counts = None
            for sub in self._subs:
                sub._tally = None

    def _attach_tally(self, sub: Subscription) -> None:
        counts = self._counts
        if counts is None or sub.raw:
            return
        with self._lock:
            if sub._tally is None:
                sub._tally = counts.tally(sub.key_expr)

    def _forget(self, items: list, item: object) -> None:
        """A closed entity leaves the bus's books (long-running processes open and close many)."""
        with self._lock:
            if item in items:
                items.remove(item)

    def _wire(self, key: str) -> str:
        return f"{self.namespace}/{key}" if self.namespace else key

    def _local(self, key: str) -> str:
        if self.namespace and key.startswith(self.namespace + "/"):
            return key[len(self.namespace) + 1:]
        return key

    def _declare(self, sub: Subscription) -> None:
        raise NotImplementedError

    def _undeclare(self, sub: Subscription) -> None:
        raise NotImplementedError

    def _declare_token(self, tok: Token) -> None:
        raise NotImplementedError

    def _undeclare_token(self, tok: Token) -> None:
        raise NotImplementedError

    def _declare_watch(self, w: LivelinessWatch, history: bool) -> None:
        raise NotImplementedError

    def _undeclare_watch(self, w: LivelinessWatch) -> None:
        raise NotImplementedError

    def _declare_queryable(self, key: str,
                           answer: Callable[[], list[tuple[str, bytes]]]) -> Closing:
        raise NotImplementedError

    def _query(self, key_expr: str, timeout: float) -> Iterable[tuple[str, str, bytes]]:
        """The replies as (local key, encoding, payload)."""
        raise NotImplementedError

    def _close_impl(self) -> None:
        pass


class _NoWatch(Closing):
    def close(self) -> None:
        pass
