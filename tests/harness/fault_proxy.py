"""A small TCP fault proxy for network-fault tests: latency and jitter, cuts, one-way stalls.

`tc netem` is not available on these machines, so a robot's link to the router goes through
this proxy instead: it listens on loopback, forwards every connection to the target, and can
delay each chunk (order kept), cut the link (close connections, refuse new ones) and restore
it, or stall one direction (bytes held, not delivered, until the stall ends — Zenoh then sees a
half-dead link and its lease expires on one side first). Sockets and threads only: no Zenoh in
this process, so it is safe to run inside the test process.
"""

from __future__ import annotations

import random
import socket
import threading
import time
from collections import deque


class _Pipe:
    """One direction of one connection: recv from `src`, deliver to `dst` after a delay."""

    def __init__(self, proxy: "FaultProxy", src: socket.socket, dst: socket.socket, direction: str):
        self.proxy, self.src, self.dst, self.direction = proxy, src, dst, direction
        self.queue: deque = deque()
        self.cond = threading.Condition()
        self.closed = False
        threading.Thread(target=self._read, daemon=True).start()
        threading.Thread(target=self._write, daemon=True).start()

    def _read(self) -> None:
        last_due = 0.0
        try:
            while not self.closed:
                data = self.src.recv(65536)
                if not data:
                    break
                latency, jitter = self.proxy.latency, self.proxy.jitter
                due = max(last_due, time.monotonic() + latency + self.proxy.rng.uniform(0, jitter))
                last_due = due
                with self.cond:
                    self.queue.append((due, data))
                    self.cond.notify()
        except OSError:
            pass
        self.close()

    def _write(self) -> None:
        try:
            while True:
                with self.cond:
                    while not self.queue and not self.closed:
                        self.cond.wait(0.1)
                    if self.closed and not self.queue:
                        return
                    due, data = self.queue[0]
                    now = time.monotonic()
                    if due > now or self.proxy.stalled(self.direction):
                        self.cond.wait(min(max(due - now, 0.005), 0.05))
                        continue
                    self.queue.popleft()
                self.dst.sendall(data)
        except OSError:
            self.close()

    def close(self) -> None:
        with self.cond:
            if self.closed:
                return
            self.closed = True
            self.cond.notify_all()
        for s in (self.src, self.dst):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            s.close()


class FaultProxy:
    """Listens on 127.0.0.1:`port` (0: any free port) and forwards to 127.0.0.1:`target`."""

    def __init__(self, target: int, port: int = 0, seed: int = 0):
        self.target = target
        self.rng = random.Random(seed)
        self.latency = 0.0
        self.jitter = 0.0
        self._cut = False
        self._stall: set[str] = set()  # "up" (client → target) and/or "down"
        self._pipes: list[_Pipe] = []
        self._lock = threading.Lock()
        self.server = socket.socket()
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(("127.0.0.1", port))
        self.server.listen(16)
        self.port = self.server.getsockname()[1]
        self._stop = False
        threading.Thread(target=self._accept, daemon=True).start()

    @property
    def endpoint(self) -> str:
        return f"tcp/127.0.0.1:{self.port}"

    def _accept(self) -> None:
        while not self._stop:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            if self._cut:
                client.close()
                continue
            try:
                upstream = socket.create_connection(("127.0.0.1", self.target), timeout=2)
                upstream.settimeout(None)
            except OSError:
                client.close()
                continue
            for s in (client, upstream):
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                self._pipes += [_Pipe(self, client, upstream, "up"),
                                _Pipe(self, upstream, client, "down")]

    def stalled(self, direction: str) -> bool:
        return direction in self._stall

    def set_latency(self, latency: float, jitter: float = 0.0) -> None:
        self.latency, self.jitter = latency, jitter

    def cut(self) -> None:
        """The link goes down: open connections are closed, new ones refused."""
        self._cut = True
        with self._lock:
            pipes, self._pipes = self._pipes, []
        for p in pipes:
            p.close()

    def heal(self) -> None:
        self._cut = False
        self._stall.clear()

    def stall(self, direction: str) -> None:
        """Hold every byte going `up` (to the target) or `down` (to the client)."""
        self._stall.add(direction)

    def close(self) -> None:
        self._stop = True
        self.cut()
        self.server.close()
