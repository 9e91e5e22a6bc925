"""How a process joins the bus: the options every networked command shares, checked up front.

Zero configuration (no --connect, --listen or config file) means: peer mode on loopback with
multicast scouting off; bind the rendezvous endpoint if it is free, otherwise join whoever holds
it. When the holder exits, the next process to start takes the rendezvous over and the older
peers reconnect to it by retry, so any start order works and nobody is special for long.

The default rendezvous, 7447, is also Zenoh's and rmw_zenohd's port: on a ROS 2 robot it is
held by the robot's router. Whoever holds our rendezvous also holds an abstract socket named
after it (`_MARKER`, Linux; released by the kernel when the process ends), so a process can tell
our holder from someone else's: when the default port is held by something that is not ours, the
rendezvous moves to the next port that is free or ours (7448, …) — every one of our processes
makes the same choice — and says so in a warning, instead of mixing our bus into the robot's.
An explicit rendezvous (`$MRTA_RENDEZVOUS`, `rendezvous=`) is used as given.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import socket
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from ..keys import validate_key_expr

DEFAULT_RENDEZVOUS = "tcp/127.0.0.1:7447"
RENDEZVOUS_ENV = "MRTA_RENDEZVOUS"
RENDEZVOUS_TRIES = 16  # ports after the default looked at before giving up on moving
_MARKER = "mrta-rendezvous-{}"  # abstract socket held by the holder of our rendezvous (port)
_markers: dict[int, socket.socket] = {}  # markers this process holds, for its whole life
_warned: set[int] = set()
log = logging.getLogger("mrta.bus")
MODES = ("peer", "client", "router")
MAX_CONFIG_BYTES = 1024 * 1024  # a Zenoh config is a few kB; the file is read whole

_ENDPOINT = re.compile(r"^(tcp|udp|tls|quic|ws|unixsock-stream|unixpipe)/(.+)$")
_HOSTPORT = re.compile(r"^(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.\-]+):(\d{1,5})(#.*)?$")


def private_rendezvous() -> str:
    """`tcp/127.0.0.1:PORT` on a port free right now: a rendezvous of one's own, so a demo, a
    test or a benchmark never meets (or blocks) whoever uses the default 7447."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{s.getsockname()[1]}"


def check_endpoint(endpoint: str, what: str = "endpoint") -> str:
    """`tcp/127.0.0.1:7447`-style endpoints; one clear error naming the value otherwise."""
    m = _ENDPOINT.match(endpoint)
    if not m:
        raise ConfigError(
            f"invalid {what} {endpoint!r}: expected PROTOCOL/ADDRESS, e.g. tcp/127.0.0.1:7447"
        )
    proto, addr = m.groups()
    if proto in ("tcp", "udp", "tls", "quic", "ws"):
        hp = _HOSTPORT.match(addr)
        if not hp or not 0 <= int(hp.group(2)) <= 65535:
            raise ConfigError(f"invalid {what} {endpoint!r}: expected HOST:PORT with a port 0-65535")
    return endpoint


# The Zenoh lease: how long the others wait for a silent process (no CPU, SIGSTOP, a cut
# cable) before they drop its link and its tokens go — a killed one's socket closes at once. It
# is the silent process's own: each side advertises its lease and the others expire it by that
# (measured: a peer with 30 s stopped for 20 s kept its link to one with 3 s; one with 3 s
# stopped was dropped after 3 s). 3 s by default; a mission run in lockstep gives its processes
# lockstep's wait for a live participant instead, through $MRTA_LEASE (supervisor/mission/
# runner.py, run_lease): there a starved process is waited for, as lockstep waits for it.
LEASE = 3.0
LEASE_ENV = "MRTA_LEASE"
MAX_LEASE = 3600.0


def lease_from_env() -> float:
    """$MRTA_LEASE (seconds), or LEASE when unset; ConfigError naming it when it is not a
    number of seconds in (0, MAX_LEASE]."""
    raw = os.environ.get(LEASE_ENV, "").strip()
    if not raw:
        return LEASE
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not 0 < value <= MAX_LEASE:  # NaN and infinity fail it too
        raise ConfigError(f"${LEASE_ENV} {raw!r}: expected a number of seconds, more than 0 "
                          f"and at most {MAX_LEASE:g}")
    return value


@dataclass
class BusOptions:
    mode: str = "peer"
    connect: list[str] = field(default_factory=list)
    listen: list[str] = field(default_factory=list)
    zenoh_config: Path | None = None
    namespace: str = ""
    rendezvous: str = ""  # empty: $MRTA_RENDEZVOUS or the default
    lease: float | None = None  # seconds; None: $MRTA_LEASE or LEASE

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ConfigError(f"invalid mode {self.mode!r}: expected one of {', '.join(MODES)}")
        for e in self.connect:
            check_endpoint(e, "--connect endpoint")
        for e in self.listen:
            check_endpoint(e, "--listen endpoint")
        if self.rendezvous:
            check_endpoint(self.rendezvous, "rendezvous endpoint")

    @property
    def lease_seconds(self) -> float:
        return self.lease if self.lease is not None else lease_from_env()

    @property
    def rendezvous_endpoint(self) -> str:
        if self.rendezvous:
            return self.rendezvous
        env = os.environ.get(RENDEZVOUS_ENV, "").strip()
        return check_endpoint(env, f"${RENDEZVOUS_ENV}") if env else default_rendezvous()

    @property
    def zero_config(self) -> bool:
        return not (self.connect or self.listen or self.zenoh_config) and self.mode == "peer"

    def user_config(self) -> dict[str, Any]:
        """The --zenoh-config file as a dict (JSON5); ConfigError naming the file (and the line
        where the parser gives one) if it cannot be read or parsed: not UTF-8, nested past
        the parser's recursion, over MAX_CONFIG_BYTES, or not an object."""
        if self.zenoh_config is None:
            return {}
        import json5  # only needed for this option

        path = Path(self.zenoh_config)
        try:
            with path.open("rb") as f:
                raw = f.read(MAX_CONFIG_BYTES + 1)
        except OSError as exc:
            raise ConfigError(f"cannot read Zenoh config file: {exc.strerror}",
                              file=str(path)) from None
        if len(raw) > MAX_CONFIG_BYTES:
            raise ConfigError(f"larger than {MAX_CONFIG_BYTES // 1024} kB: not a Zenoh config "
                              "file", file=str(path))
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError("not a UTF-8 text file", file=str(path),
                              line=raw.count(b"\n", 0, exc.start) + 1) from None
        try:
            data = json5.loads(text)
        except RecursionError:
            raise ConfigError("invalid JSON5: nested too deeply", file=str(path)) from None
        except ValueError as exc:
            raise ConfigError(f"invalid JSON5: {str(exc).replace('<string>', 'line')}",
                              file=str(path)) from None
        if not isinstance(data, dict):
            raise ConfigError(f"a Zenoh config must be a JSON5 object, got {type(data).__name__}",
                              file=str(path))
        return data

    def check(self) -> None:
        """What a command checks before it starts anything: the --zenoh-config file read
        (user_config) and, merged over our defaults, accepted by Zenoh itself key by key —
        an unknown key or a value of the wrong type is bad input naming the file and the key,
        not a failure when the session opens."""
        if self.namespace:
            validate_key_expr(self.namespace)
        user = self.user_config()
        if not user:
            return
        import zenoh  # the bus package's own dependency; every networked command loads it

        conf = zenoh.Config()
        merged = merge(base_config(self.mode, self.lease_seconds), user)
        for key in user:
            try:
                # NaN and Infinity are JSON5, not JSON: Zenoh would read a NaN lease as 0
                conf.insert_json5(key, json.dumps(merged[key], allow_nan=False))
            except zenoh.ZError as exc:
                raise ConfigError(f"Zenoh refuses {key!r}: {zenoh_problem(str(exc))}",
                                  file=str(self.zenoh_config)) from None
            except ValueError:
                raise ConfigError(f"{key!r}: NaN and Infinity are not numbers Zenoh can take",
                                  file=str(self.zenoh_config)) from None


def zenoh_problem(text: str) -> str:
    """The reason in a Zenoh config error, without the Rust source location and debug
    wrapping around it (`Json5Err(Message { msg: "…", location: … }) at /root/.cargo/…`)."""
    m = (re.search(r'msg: "((?:[^"\\]|\\.)*)"', text)
         or re.search(r'Str\("((?:[^"\\]|\\.)*)"\)', text))
    reason = m.group(1) if m else text.split(" at /", 1)[0]
    return " ".join(reason.split(" at /", 1)[0].split())


def _port_of(endpoint: str) -> int | None:
    m = re.match(r"^tcp/127\.0\.0\.1:(\d+)$", endpoint)
    return int(m.group(1)) if m else None


def _port_free(port: int) -> bool:
    """Whether nobody listens on the loopback port. SO_REUSEADDR, as Zenoh binds: connections of
    a holder that has just exited (TIME_WAIT) must not make its port look held by a stranger."""
    with socket.socket() as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


def _hold_marker(port: int) -> bool:
    """Take the marker of our rendezvous on `port`; False if another process holds it."""
    if port in _markers:
        return True
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        s.bind("\0" + _MARKER.format(port))
    except OSError:
        s.close()
        return False
    _markers[port] = s
    return True


def _marked_by_other(port: int) -> bool:
    if port in _markers:
        return False
    s = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    try:
        s.bind("\0" + _MARKER.format(port))
    except OSError:
        return True
    finally:
        s.close()
    return False


def default_rendezvous() -> str:
    """DEFAULT_RENDEZVOUS, unless its port is held by something that is not ours (no marker):
    then the next port that is free or ours, with a warning (the module's docstring says why)."""
    first = _port_of(DEFAULT_RENDEZVOUS)
    if first is None or not sys.platform.startswith("linux"):
        return DEFAULT_RENDEZVOUS
    for port in range(first, min(first + RENDEZVOUS_TRIES, 65536)):
        if port in _markers or _port_free(port) or _marked_by_other(port):
            chosen = f"tcp/127.0.0.1:{port}"
            if port != first and port not in _warned:
                _warned.add(port)
                log.warning("%s is held by something that is not ours (rmw_zenohd or another "
                            "Zenoh router?): our rendezvous is %s (set $%s to choose)",
                            DEFAULT_RENDEZVOUS, chosen, RENDEZVOUS_ENV)
            return chosen
    return DEFAULT_RENDEZVOUS


SLOW_READER_US = 30_000_000  # µs a live reader too slow for our reliable samples is waited for


def base_config(mode: str, lease: float = LEASE) -> dict[str, Any]:
    """Our defaults: loopback only, multicast scouting off, gossip to find the other peers;
    `lease` in seconds (LEASE)."""
    return {
        "mode": mode,
        "scouting": {
            "delay": 10,
            "multicast": {"enabled": False},
            "gossip": {"enabled": True, "multihop": False,
                       "autoconnect": {"peer": ["router", "peer"], "router": ["router", "peer"]}},
        },
        "connect": {
            "endpoints": [],
            "exit_on_failure": False,
            "retry": {"period_init_ms": 100, "period_max_ms": 1000, "period_increase_factor": 1.5},
        },
        "listen": {"endpoints": ["tcp/127.0.0.1:0"]},
        # lease (LEASE, 3 s): a frozen peer is dropped after it. wait_before_drop 1 µs
        # (default 1 ms): a lossy put towards a peer whose queue is full gives up at once — with 1 ms per put,
        # a stopped observer still held a simulator publishing 10,000 samples/s to ~1,000/s
        # open/accept timeouts 2 s (default 10 s): a connection attempt to a frozen peer
        # (SIGSTOP) otherwise holds session.close() for 10 s
        # data queue 16 batches per link (default 2): bursts from a simulator at full speed are
        # absorbed instead of dropped for a subscriber that keeps up on average (a recorder)
        # shared memory off: with it, a process's first sample over 3 kB maps a 16 MB pool of
        # its own, all of it resident — an agent of a 20-robot team sends such samples, so
        # 16 MB more per agent (benchmarks/team_sizes.py), for a copy saved on a few kB
        # wait_before_close 30 s (default 5 s): Zenoh closes a link whose reliable (BLOCK)
        # samples could not be queued for that long — a reader too slow, not a dead one (the
        # lease finds those). On a busy machine a live reader is that slow now and then: the
        # README's 20-robot walkthrough at load 25 had the router cut the runner's link three
        # times (every token seemed to go at once), the recorder's and three agents' once each,
        # dropping what was queued to them — a hole in the recording, claims forgiven, a run
        # called incomplete because the machine was busy. A slow reader is waited for as long
        # as lockstep waits for a live participant (lockstep.protocol.DEFAULT_TIMEOUT), past
        # which lockstep gives it up anyway
        "transport": {"link": {"tx": {"lease": round(lease * 1000), "queue": {
            "size": {"data": 16},
            "congestion_control": {"drop": {"wait_before_drop": 1},
                                   "block": {"wait_before_close": SLOW_READER_US}}}}},
            "unicast": {"open_timeout": 2000, "accept_timeout": 2000},
            "shared_memory": {"enabled": False}},
    }


def merge(base: dict, over: dict) -> dict:
    out = dict(base)
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merge(out[k], v)
        else:
            out[k] = v
    return out


def session_configs(opts: BusOptions) -> list[dict[str, Any]]:
    """Configs to try in order: the first that opens is used (bind-or-join in zero-config mode)."""
    cfg = merge(base_config(opts.mode, opts.lease_seconds), opts.user_config())
    if opts.mode == "client":
        cfg["listen"] = {"endpoints": []}
        if not opts.connect and not cfg["connect"].get("endpoints"):
            cfg["connect"]["endpoints"] = [opts.rendezvous_endpoint]
    if opts.listen:
        cfg["listen"] = {"endpoints": list(opts.listen)}
    if opts.connect:
        cfg["connect"]["endpoints"] = list(opts.connect)
    if not opts.zero_config:
        _mark_rendezvous(cfg["listen"].get("endpoints", []))
        return [cfg]
    rv = opts.rendezvous_endpoint
    _mark_rendezvous([rv])  # we try to bind it first: if we get it, it is marked ours
    bind = merge(cfg, {"listen": {"endpoints": [rv, "tcp/127.0.0.1:0"]}})
    join = merge(cfg, {"connect": {"endpoints": [rv]}})
    return [bind, join]


def _mark_rendezvous(endpoints: list) -> None:
    """Hold the marker of each loopback port we are about to listen on (a `mrta router` on the
    rendezvous is ours too), if it is free."""
    for e in endpoints:
        port = _port_of(str(e))
        if port and _port_free(port):
            _hold_marker(port)
