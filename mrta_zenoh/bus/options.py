"""How a process joins the bus: the options every networked command shares, checked up front.

Zero configuration (no --connect, --listen or config file) means: peer mode on loopback with
multicast scouting off; bind the rendezvous endpoint if it is free, otherwise join whoever holds
it. When the holder exits, the next process to start takes the rendezvous over and the older
peers reconnect to it by retry, so any start order works and nobody is special for long.
"""

from __future__ import annotations

import os
import re
import socket
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import ConfigError

DEFAULT_RENDEZVOUS = "tcp/127.0.0.1:7447"
RENDEZVOUS_ENV = "MRTA_RENDEZVOUS"
MODES = ("peer", "client", "router")

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


@dataclass
class BusOptions:
    mode: str = "peer"
    connect: list[str] = field(default_factory=list)
    listen: list[str] = field(default_factory=list)
    zenoh_config: Path | None = None
    namespace: str = ""
    rendezvous: str = ""  # empty: $MRTA_RENDEZVOUS or the default

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
    def rendezvous_endpoint(self) -> str:
        if self.rendezvous:
            return self.rendezvous
        env = os.environ.get(RENDEZVOUS_ENV, "").strip()
        return check_endpoint(env, f"${RENDEZVOUS_ENV}") if env else DEFAULT_RENDEZVOUS

    @property
    def zero_config(self) -> bool:
        return not (self.connect or self.listen or self.zenoh_config) and self.mode == "peer"

    def user_config(self) -> dict[str, Any]:
        """The --zenoh-config file as a dict (JSON5); ConfigError naming file and line if bad."""
        if self.zenoh_config is None:
            return {}
        import json5  # only needed for this option

        path = Path(self.zenoh_config)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read Zenoh config file: {exc.strerror}") from None
        try:
            data = json5.loads(text)
        except ValueError as exc:
            raise ConfigError(f"{path}: invalid JSON5: {str(exc).replace('<string>', 'line')}") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: a Zenoh config must be a JSON5 object, got {type(data).__name__}")
        return data


def base_config(mode: str) -> dict[str, Any]:
    """Our defaults: loopback only, multicast scouting off, gossip to find the other peers."""
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
        # lease 3 s: a frozen peer is dropped after 3 s. wait_before_drop 1 µs (default 1 ms):
        # a lossy put towards a peer whose queue is full gives up at once — with 1 ms per put,
        # a stopped observer still held a simulator publishing 10,000 samples/s to ~1,000/s
        # open/accept timeouts 2 s (default 10 s): a connection attempt to a frozen peer
        # (SIGSTOP) otherwise holds session.close() for 10 s
        # data queue 16 batches per link (default 2): bursts from a simulator at full speed are
        # absorbed instead of dropped for a subscriber that keeps up on average (a recorder)
        "transport": {"link": {"tx": {"lease": 3000, "queue": {
            "size": {"data": 16},
            "congestion_control": {"drop": {"wait_before_drop": 1}}}}},
            "unicast": {"open_timeout": 2000, "accept_timeout": 2000}},
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
    cfg = merge(base_config(opts.mode), opts.user_config())
    if opts.mode == "client":
        cfg["listen"] = {"endpoints": []}
        if not opts.connect and not cfg["connect"].get("endpoints"):
            cfg["connect"]["endpoints"] = [opts.rendezvous_endpoint]
    if opts.listen:
        cfg["listen"] = {"endpoints": list(opts.listen)}
    if opts.connect:
        cfg["connect"]["endpoints"] = list(opts.connect)
    if not opts.zero_config:
        return [cfg]
    rv = opts.rendezvous_endpoint
    bind = merge(cfg, {"listen": {"endpoints": [rv, "tcp/127.0.0.1:0"]}})
    join = merge(cfg, {"connect": {"endpoints": [rv]}})
    return [bind, join]
