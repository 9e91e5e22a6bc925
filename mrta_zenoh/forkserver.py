"""A fork server: one interpreter that imported the run's modules once, forking every process
of an experiment's runs instead of starting a fresh interpreter for each (issue 48).

Why: a study run is four Python processes — the runner (`mrta demo`), the recorder, the
simulator, an agent host — and each fresh interpreter imported the project again: about a
quarter of a 5-robot run's CPU. An experiment (supervisor/experiment/api.py) starts this server
before its first run and names its socket in `$MRTA_FORKSERVER`; from then on
`mrta_zenoh.processes.Child` asks it for every `python -m MODULE ARGS…` child of this
interpreter (the runs, and their runs' own children, which inherit the variable). The server
imports the modules it is given, then forks one child per request: the child runs MODULE as
`python -m` would (its argv, environment, working directory and sys.path[0]), its stdin on
/dev/null and its stdout/stderr on the caller's pipes. The caller gets the child's pid (it
signals it itself, by pid, as before) and, on the same connection, its exit code.

Fork safety (docs/zenoh.md, "Fork"): the server never opens a Zenoh session and starts no
thread, so its children are forked from a process with one thread and no Zenoh runtime — the
state a fresh interpreter starts in. A child does what a fresh one does: `random` is reseeded
by Python at fork; everything seeded comes from the run seed. What it does not redo: module
imports (the modules are the same files) and the hash seed (one per server, random; no row
depends on it — a resumed study's rows are byte-identical to fresh ones).

Ends: a child whose caller disconnects (the caller ended, even by `kill -9`) gets SIGTERM, as
`lifecycle.die_with_parent` gives a fresh child; the children's `$MRTA_PARENT_PID` is the
server, so they stop if it goes. The server ends on SIGINT/SIGTERM, or when its parent goes.
"""

from __future__ import annotations

import gc
import importlib
import json
import logging
import os
import runpy
import selectors
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from typing import IO, TYPE_CHECKING

from .errors import MrtaRuntimeError
from .lifecycle import PARENT_ENV

log = logging.getLogger("mrta.forkserver")

if TYPE_CHECKING:
    from .processes import Child, ProcessGroup

SOCKET_ENV = "MRTA_FORKSERVER"  # the server's socket path, for every Child of this interpreter
READY = "forkserver ready"
FORKED = "forkserver forked"  # its last line: how many processes it forked
_MAX_MESSAGE = 1 << 20  # bytes: a request is argv + environment + working directory
_KILL_AFTER = 10.0  # seconds from SIGTERM to SIGKILL for a child whose caller went


# ---- caller's side ----------------------------------------------------------------------

def forkable(argv: list[str], env: dict) -> bool:
    """Whether `argv` is `python -m MODULE …` in this interpreter and `env`, the child's
    environment, names a server."""
    return bool(env.get(SOCKET_ENV)) and len(argv) >= 3 \
        and argv[0] == sys.executable and argv[1] == "-m"


class ForkedProcess:
    """The part of subprocess.Popen that mrta_zenoh.processes uses (pid, stdout, stderr, poll,
    wait), for a child the server forked: the exit code comes over the connection."""

    def __init__(self, argv: list[str], env: dict, cwd: str | None, merge_stderr: bool):
        self.args = argv
        self.returncode: int | None = None
        self._conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self._lock = threading.Lock()
        self._buffer = b""
        out_r, out_w = os.pipe()
        err_r, err_w = (out_r, out_w) if merge_stderr else os.pipe()
        try:
            self._conn.connect(env[SOCKET_ENV])
            request = {"module": argv[2], "args": argv[3:], "env": env,
                       "cwd": os.path.abspath(cwd or os.getcwd())}
            socket.send_fds(self._conn, [json.dumps(request).encode() + b"\n"], [out_w, err_w])
            reply = self._read_message()
        except OSError as exc:
            self._conn.close()
            raise MrtaRuntimeError(f"fork server at ${SOCKET_ENV}: {exc}") from exc
        finally:
            os.close(out_w)
            if not merge_stderr:
                os.close(err_w)
        if reply is None or "pid" not in reply:
            raise MrtaRuntimeError(f"fork server refused {argv[2]}: {reply}")
        self.pid: int = reply["pid"]
        self.stdout: IO[str] = open(out_r, "r")  # text, as Popen(text=True) reads it
        self.stderr: IO[str] | None = None if merge_stderr else open(err_r, "r")

    def _read_message(self, timeout: float | None = None) -> dict | None:
        """One JSON line from the server; None at end of stream; TimeoutError if none came."""
        while b"\n" not in self._buffer:
            self._conn.settimeout(timeout)
            try:
                data = self._conn.recv(4096)
            except (socket.timeout, BlockingIOError):  # a timeout of 0: non-blocking
                raise TimeoutError from None
            if not data:
                return None
            self._buffer += data
        line, self._buffer = self._buffer.split(b"\n", 1)
        return json.loads(line)

    def _wait_exit(self, timeout: float | None) -> int | None:
        with self._lock:
            if self.returncode is not None:
                return self.returncode
            try:
                message = self._read_message(timeout)
            except TimeoutError:
                return None
            # no exit message: the server went, and its children with it (they are ended
            # when their parent goes), so the child was ended from outside
            self.returncode = -signal.SIGKILL if message is None else int(message["exit"])
            self._conn.close()
            return self.returncode

    def poll(self) -> int | None:
        return self._wait_exit(0.0)

    def wait(self, timeout: float | None = None) -> int:
        rc = self._wait_exit(timeout)
        if rc is None:
            raise subprocess.TimeoutExpired(self.args, timeout)
        return rc


# ---- server's side ----------------------------------------------------------------------

class _Server:
    def __init__(self, path: str):
        self.listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.listener.bind(path)
        self.listener.listen(64)
        self.wake_r, self.wake_w = os.pipe()
        os.set_blocking(self.wake_w, False)
        signal.signal(signal.SIGCHLD, lambda *_: None)
        signal.set_wakeup_fd(self.wake_w)
        self.selector = selectors.DefaultSelector()
        self.selector.register(self.listener, selectors.EVENT_READ, "accept")
        self.selector.register(self.wake_r, selectors.EVENT_READ, "wake")
        self.children: dict[int, socket.socket] = {}   # pid → its caller's connection
        self.orphans: dict[int, float] = {}            # pid → when it was sent SIGTERM
        self.forked = 0

    def serve(self, parent: int) -> dict | None:
        """Serve until stopped (None) or, in a forked child, return its request."""
        while os.getppid() == parent:
            for key, _ in self.selector.select(timeout=0.5):
                if key.data == "accept":
                    conn, _ = self.listener.accept()
                    self.selector.register(conn, selectors.EVENT_READ, "request")
                elif key.data == "wake":
                    os.read(self.wake_r, 4096)
                    self._reap()
                elif key.data == "caller":
                    self._on_caller(key.fileobj)
                else:
                    request = self._on_request(key.fileobj)
                    if request is not None:
                        return request
            self._kill_late_orphans()
        return None

    def _on_caller(self, conn: socket.socket) -> None:
        """A caller's connection is readable: it says nothing, so it closed or went."""
        self.selector.unregister(conn)
        conn.close()
        for pid, c in list(self.children.items()):
            if c is conn:
                del self.children[pid]
                self._end(pid)

    def _on_request(self, conn: socket.socket) -> dict | None:
        """Fork the child `conn` asks for; in the child, return its request."""
        self.selector.unregister(conn)
        try:
            data, fds, _, _ = socket.recv_fds(conn, _MAX_MESSAGE, 2)
            request = json.loads(data)
        except (OSError, ValueError) as exc:
            conn.close()
            print(f"forkserver: bad request: {exc}", file=sys.stderr)
            return None
        self.forked += 1
        pid = os.fork()
        if pid == 0:
            self._become_child(conn, fds)
            return request
        for fd in set(fds):
            os.close(fd)
        try:
            conn.sendall(json.dumps({"pid": pid}).encode() + b"\n")
        except OSError:  # the caller went before hearing of its child
            conn.close()
            self._end(pid)
            return None
        self.children[pid] = conn
        self.selector.register(conn, selectors.EVENT_READ, "caller")
        return None

    def _become_child(self, conn: socket.socket, fds: list[int]) -> None:
        signal.set_wakeup_fd(-1)
        signal.signal(signal.SIGCHLD, signal.SIG_DFL)
        self.selector.close()
        for s in [self.listener, conn, *self.children.values()]:
            s.close()
        os.close(self.wake_r)
        os.close(self.wake_w)
        null = os.open(os.devnull, os.O_RDONLY)
        os.dup2(null, 0)
        os.dup2(fds[0], 1)
        os.dup2(fds[1], 2)
        for fd in {null, *fds}:
            os.close(fd)

    def _reap(self) -> None:
        while True:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            self.orphans.pop(pid, None)
            conn = self.children.pop(pid, None)
            if conn is not None:
                self.selector.unregister(conn)
                try:
                    conn.sendall(json.dumps(
                        {"exit": os.waitstatus_to_exitcode(status)}).encode() + b"\n")
                except OSError:
                    pass  # the caller went meanwhile: nobody to tell
                conn.close()

    def _end(self, pid: int) -> None:
        """SIGTERM a child whose caller went, SIGKILL later (lifecycle.die_with_parent)."""
        self.orphans[pid] = time.monotonic()
        _signal(pid, signal.SIGTERM)

    def _kill_late_orphans(self) -> None:
        for pid, since in list(self.orphans.items()):
            if time.monotonic() - since > _KILL_AFTER:
                _signal(pid, signal.SIGKILL)
                del self.orphans[pid]


def _signal(pid: int, sig: int) -> None:
    """Signal `pid`, which may have ended already (then there is nothing to do)."""
    try:
        os.kill(pid, sig)
    except ProcessLookupError:
        pass


def _run_request(request: dict) -> None:
    """In the forked child: become `python -m MODULE ARGS…` as a fresh interpreter would."""
    os.environ.clear()
    os.environ.update(request["env"])
    os.environ[PARENT_ENV] = str(os.getppid())  # die with the server, which reaps us
    os.chdir(request["cwd"])
    sys.path[0] = request["cwd"]  # what `-m` puts first
    sys.argv = [request["module"], *request["args"]]
    _name_process(request["args"])
    runpy.run_module(request["module"], run_name="__main__", alter_sys=True)


def _name_process(args: list[str]) -> None:
    """Its name in `top` and /proc/PID/comm: the program's first word that is no option
    (`demo`, `record`, `simulator/sim`, `robot_agent/host`). Its command line in `ps` stays the
    server's: Python cannot rewrite it without a C extension (setproctitle)."""
    word = next((a for a in args if not a.startswith("-")), "")
    if word:
        try:
            with open("/proc/self/comm", "w") as f:
                f.write(word[-15:])  # the kernel keeps 15 bytes
        except OSError:
            pass  # not Linux's /proc: the name is cosmetic


def main(argv: list[str]) -> int:
    """`python -m mrta_zenoh.forkserver SOCKET MODULE…`: import the modules, say READY on
    stdout, serve until SIGINT/SIGTERM or until the parent goes."""
    path, modules = argv[0], argv[1:]
    parent = os.getppid()
    os.environ.pop(PARENT_ENV, None)
    os.environ.pop(SOCKET_ENV, None)
    for name in modules:
        importlib.import_module(name)
    if threading.active_count() != 1:
        print(f"forkserver: importing {modules} started threads: cannot fork safely",
              file=sys.stderr)
        return 1
    gc.collect()
    gc.freeze()  # the children do not copy the imported modules' pages by counting them
    server = _Server(path)
    print(READY, flush=True)
    try:
        request = server.serve(parent)
    except KeyboardInterrupt:
        request = None
    if request is None:
        print(f"{FORKED} {server.forked}", flush=True)
        return 0
    _run_request(request)  # a forked child: from here on it is that program
    return 0


SERVER = "forkserver"  # its name among the group's children
_folders: dict[int, tempfile.TemporaryDirectory] = {}  # a running server's socket folder


def ensure(group: "ProcessGroup", modules: list[str], timeout: float = 600.0) -> "Child":
    """The group's fork server, started first if the group has none running: it imports
    `modules` and is named in the group's environment, so that every child the group starts
    from then on (and their children) is forked by it. Started on demand, by the first
    run that needs it, not by an experiment whose runs are stand-ins (the tests'). `timeout`:
    seconds to wait for it to be ready (its imports, on a loaded machine)."""
    for child in group.children:
        if child.name == SERVER and child.running():
            return child
    # the socket in a folder only this user can enter: whoever can connect can have the
    # server run any module as this user (finish() removes it)
    folder = tempfile.TemporaryDirectory(prefix="mrta-fork-")
    path = os.path.join(folder.name, "socket")  # a short path: AF_UNIX allows 107 bytes
    group.env.pop(SOCKET_ENV, None)
    server = group.start([sys.executable, "-m", "mrta_zenoh.forkserver", path, *modules],
                         name=SERVER)
    _folders[server.pid] = folder
    try:
        server.wait_line(lambda line: line == READY, timeout)
    except (TimeoutError, AssertionError) as exc:
        server.stop()
        _folders.pop(server.pid).cleanup()
        raise MrtaRuntimeError(f"the fork server did not start: {exc}") from None
    group.env[SOCKET_ENV] = path
    return server


def servers(group: "ProcessGroup") -> list["Child"]:
    """The group's fork servers: to stop after every other child (ProcessGroup.stop_all's
    `later`), whose exit codes they report."""
    return [child for child in group.children if child.name == SERVER]


def finish(group: "ProcessGroup") -> None:
    """Stop the group (its fork server last) and log how many processes the server forked."""
    group.env.pop(SOCKET_ENV, None)
    group.stop_all(later=servers(group))
    for server in servers(group):
        folder = _folders.pop(server.pid, None)
        if folder is not None:
            folder.cleanup()
        said = [line for line in server.stdout if line.startswith(FORKED)]
        log.info("the fork server forked %s", said[-1].split()[-1] + " processes" if said
                 else f"an unknown number of processes ({server.describe_exit()})")


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
