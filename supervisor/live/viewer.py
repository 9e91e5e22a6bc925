"""`mrta view`: the bus, the scene and the supervisor, served live to Foxglove / Lichtblick over
the Foxglove WebSocket protocol (supervisor/live/foxglove_server.py: either subprotocol name, latched
channels; loopback by default) and/or written to an MCAP file with the same channels
(supervisor/live/foxglove.py lists them; docs/foxglove.md says why they are as they are).

Time. On the wall clock, log times are wall time and the derived channels (scene, poses,
supervisor) are refreshed `rate` times a wall second. On simulated time (`--sim-time`: the
mission runner's recorder) everything is in the simulator's time, as this process's SimClock
follows it, whatever `--speed` the run had — so a recording plays at mission speed:

* every message's log time is the simulated time it arrived at (mrta_zenoh.recording.SimLogTime:
  samples before the first clock sample are held and logged at the run's first instant; a
  restarted simulator's run is laid 1 s after the previous one's end, in the same file);
* the derived channels are sampled per simulated period — `/world` and `/robots/<id>/pose` at
  SCENE_HZ, `/supervisor/state`, `/robots/<id>/task` and `/supervisor/alarms` at SUPERVISOR_HZ
  per simulated second — driven by the clock samples as they arrive (SimPacer), not by a
  wall-time timer, so a run at `--speed 0` gets as many frames per simulated second as one at
  `--speed 1`. The recorder is no lockstep participant: the simulator never waits for it, the
  receive path only compares a number and sets an event, and a frame loop that falls behind
  skips the frames whose time has passed (one frame for the latest time, never a backlog).
  Nothing is derived before the first clock sample (there is no simulated time yet); while the
  clock stands still (a stopped or hung simulator) the supervisor's channels are still
  refreshed once a wall second, at the last simulated time, so `clock_stopped` shows.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from mrta_zenoh import codec, keys
from mrta_zenoh.architectures import architecture
from mrta_zenoh.bus import Bus, BusOptions
from mrta_zenoh.clock import EPSILON, SimClock
from mrta_zenoh.codec import DecodeError
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.identity import OBSERVER
from mrta_zenoh.keys import CLOCK, RECORDER_TOKEN
from mrta_zenoh.lifecycle import Closing
from mrta_zenoh.messages import Clock, Odometry, PointCloud, Twist
from mrta_zenoh.node import Node, NodeTime
from mrta_zenoh.recording import McapRecorder, SimLogTime, check_output, json_channel
from mrta_zenoh.tools.record import drain
from mrta_zenoh.untrusted import visible

from .api import Refresh, attach, resolve_application, serving_of
from .foxglove import FoxgloveOutputs, derived_channels
from .foxglove_server import FoxgloveServer
from .state import Supervisor
from ..mission.hook import application_watch

log = logging.getLogger("mrta.view")
SCENE_KEYS = ("world", "*/ground_truth", "*/sonar")
SCENE_HZ = 5.0  # /world and poses, per simulated second (on simulated time)
SUPERVISOR_HZ = 2.0  # /supervisor/state, /robots/<id>/task, /supervisor/alarms, likewise
STALL_EVERY = 1.0  # wall seconds between supervisor frames while simulated time stands still
POLL = 0.1  # wall seconds the frame loop waits for a clock sample before looking at `stop`
# Live channels at most: one per key, and keys come from the network (an invented key a sample
# would otherwise cost a channel for good). Beyond, samples on new keys are counted, not served.
MAX_LIVE_CHANNELS = 4096


class SimPacer:
    """Wakes the frame loop when simulated time reaches the next frame's time (`due`).

    `poke()` runs on the bus's receive path after each clock sample: a comparison, and an Event
    set only when a frame is due (or time restarted). The frame loop sets `due`; a wake-up lost
    between its wait and its clear is repeated by the next clock sample, 20 simulated ms later.
    """

    def __init__(self, clock: SimClock):
        self.clock = clock
        self.due = 0.0
        self.restarts = clock.restarts
        self._event = threading.Event()

    def poke(self) -> None:
        c = self.clock
        if c.started.is_set() and (c.now() >= self.due - EPSILON or c.restarts != self.restarts):
            self._event.set()

    def wait(self, timeout: float) -> bool:
        """Block until poked or `timeout` wall seconds; True if poked."""
        woke = self._event.wait(timeout)
        self._event.clear()
        return woke


def next_tick(now: float, period: float) -> float:
    """The first multiple of `period` after `now`: frames on a fixed simulated grid, however
    late the loop woke (the skipped ones are not made up)."""
    return (math.floor(now / period + EPSILON) + 1) * period


class LiveChannels(Closing):
    """The live channels, one per topic, served by one FoxgloveServer (supervisor/
    foxglove_server.py: both subprotocol names, latched channels, a slow client costs only
    itself). `known`: channels advertised before any message (known_channels)."""

    def __init__(self, host: str, port: int, known=()):
        self.server = FoxgloveServer(host, port)
        self.host = host
        self.refused = 0  # samples on keys beyond MAX_LIVE_CHANNELS
        for topic, schema, encoding in known:
            self.server.advertise(topic, schema, encoding)

    @property
    def url(self) -> str:
        return self.server.url

    @property
    def channels(self) -> dict:
        return self.server.by_topic

    def emit(self, topic: str, schema: tuple[str, str, bytes], encoding: str, data: bytes,
             t_ns: int) -> None:
        ch = self.server.by_topic.get(topic)
        if ch is None:
            ch = self.server.advertise(topic, schema, encoding)
        self.server.log(ch, data, t_ns)

    def emit_bus(self, key: str, schema: tuple[str, str, bytes], data: bytes, t_ns: int) -> None:
        """A bus sample on its key's channel, as JSON; a new key only while there are fewer
        than MAX_LIVE_CHANNELS channels (the derived channels are never refused)."""
        if key not in self.server.by_topic and len(self.server.by_topic) >= MAX_LIVE_CHANNELS:
            self.refused += 1
            if self.refused == 1:
                log.warning("more than %d keys: samples on new keys are not served live "
                            "(first: %s)", MAX_LIVE_CHANNELS, visible(key, 200))
            return
        self.emit(key, schema, "json", data, t_ns)

    def close(self) -> None:
        self.server.close()


@dataclass(frozen=True)
class ViewOptions:
    """What `mrta view` (and the mission's recorder) serves and records, and when.

    `port` None: no server; `output` None: no recording (one of them at least). `rate`:
    derived frames a wall second on the wall clock; `scene_hz`, `supervisor_hz`: per simulated
    second on simulated time (module docstring). `dated`: on simulated time, log times from the
    wall-clock instant the run's clock was first heard (recording.SimLogTime)."""

    app: str | None = None
    port: int | None = 8765
    host: str = "127.0.0.1"
    output: Path | None = None
    sim_time: bool = False
    dated: bool = False
    rate: float = 4.0
    duration: float | None = None
    scene_hz: float = SCENE_HZ
    supervisor_hz: float = SUPERVISOR_HZ

    def check(self) -> None:
        """ConfigError (exit 2) before anything opens."""
        if self.port is None and self.output is None:
            raise ConfigError("nothing to do: give a --port to serve, an --output to record, "
                              "or both")
        if self.output is not None:
            check_output(Path(self.output))
        if min(self.rate, self.scene_hz, self.supervisor_hz) <= 0:
            raise ConfigError("frame rates must be positive")
        if self.dated and not self.sim_time:
            raise ConfigError("--dated is for --sim-time (wall-time log times are dates already)")


def known_channels(app_model) -> list[tuple[str, tuple[str, str, bytes], str]]:
    """(topic, schema, encoding) of the channels an application's run will have, from its
    application file and its architecture's contract: each robot's simulator keys and its
    architecture's (a kind with sub-keys once per task: ALLIANCE's motivation/<task>), and the
    derived channels. Advertised when the server starts, so a layout finds its topics at once.
    An architecture with no registered contract (an rqt_mrta file only) adds none of its own."""
    robots = [r.id for r in app_model.robots]
    try:
        arch = architecture(app_model.architecture)
    except ConfigError:
        arch = None
    out = list(derived_channels(robots))

    def bus(key: str, cls) -> None:
        conv = json_channel(codec.encoding_for(cls.TYPE_NAME))
        if conv is not None:
            out.append((key, conv[0], "json"))

    bus(keys.CLOCK, Clock)
    for rid in robots:
        for key, cls in ((keys.ground_truth(rid), Odometry), (keys.odom(rid), Odometry),
                         (keys.sonar(rid), PointCloud), (keys.cmd_vel(rid), Twist)):
            bus(key, cls)
        for kind, cls in (arch.messages.items() if arch is not None else ()):
            subs = app_model.tasks() if arch.has_subkeys(kind) else [None]
            for task in subs:
                bus(arch.key(rid, kind) if task is None else arch.key(rid, kind, task), cls)
    return out


def run_view(options: ViewOptions, bus_options: BusOptions, *,
             stop: threading.Event | None = None, on_ready=None, bus: Bus | None = None) -> int:
    """Serve and/or record until `stop` (or `options.duration` wall seconds). `bus`: an open
    bus to use instead of opening one from `bus_options` (tests: the in-process bus); it is
    left open."""
    options.check()
    application = resolve_application(options.app) if options.app else None
    sim_time = options.sim_time
    node = Node(bus_options, OBSERVER, time=NodeTime.SIM if sim_time else NodeTime.WALL,
                stop=stop, bus=bus)
    clock = node.clock
    stamper = SimLogTime(clock, dated=options.dated) if sim_time else None
    log_time = stamper or time.time_ns
    pacer = SimPacer(clock) if sim_time else None
    with node, contextlib.ExitStack() as handles:
        bus, stop = node.bus, node.stop
        # closed in reverse order: subscriptions and tokens, then the recording and the server
        robots = [r.id for r in application[0].robots] \
            if application is not None else None
        live = handles.enter_context(LiveChannels(
            options.host, options.port,
            known_channels(application[0]) if application is not None else ())) \
            if options.port is not None else None
        # a recording that cannot be written stops the view at once (`stop`); closing it
        # then raises MrtaRuntimeError: exit 1, not a server that runs on recording nothing
        recorder = handles.enter_context(McapRecorder(Path(options.output), log_time=stamper,
                                                      on_error=stop.set)) \
            if options.output is not None else None
        sinks = [s for s in (live.emit if live else None, recorder.add if recorder else None)
                 if s is not None]

        def emit(topic, schema, enc, data, t_ns):
            for sink in sinks:
                sink(topic, schema, enc, data, t_ns)

        outputs = FoxgloveOutputs(emit, robots)
        on_raw = _receiver(stamper, log_time, recorder, live, pacer)
        handles.enter_context(bus.subscribe_raw("**", on_raw))
        if recorder is not None:
            handles.enter_context(bus.watch_liveliness("**", recorder.liveliness))
        for expr in SCENE_KEYS:
            handles.enter_context(bus.subscribe(
                expr, lambda s: outputs.on_sample(s.key, s.message), queue_size=100))
        sup = refresh = None
        if application is not None:
            app_model, arch = application
            sup = Supervisor(arch, app_model, clock.now(), watch=application_watch(app_model),
                             serving=serving_of(app_model.architecture))
            for h in attach(sup, bus, clock):
                handles.callback(h.close)
            refresh = Refresh(sup, clock, sim_time)
        if recorder is not None:
            handles.enter_context(bus.declare_token(f"{RECORDER_TOKEN}/{bus.zid}"))
        if live is not None:
            log.info("Foxglove: open a connection to %s", live.url)
        if on_ready is not None:
            on_ready(live.url if live is not None else None)
        start = time.monotonic()

        def over() -> bool:
            return options.duration is not None and time.monotonic() - start >= options.duration

        if pacer is None:
            while not stop.wait(1.0 / options.rate):
                outputs.frame(time.time_ns(), sup.snapshot(refresh()) if sup is not None else None)
                if over():
                    break
        else:
            _sim_frames(clock, stamper, pacer, outputs, sup, refresh, stop, over,
                        1.0 / options.scene_hz, 1.0 / options.supervisor_hz)
            if recorder is not None:
                drain(clock)
    return 0


def _receiver(stamper, log_time, recorder, live, pacer):
    """The raw subscription's callback: stamp, record, serve (as JSON), wake the frame loop."""
    converters: dict[str, object] = {}

    def on_raw(sample) -> None:
        if stamper is not None:
            stamper.observe(sample.key, sample.encoding, sample.payload)
        t = log_time()
        if recorder is not None:
            recorder.sample(sample.key, sample.encoding, sample.payload, t)
        if live is not None:
            conv = converters.get(sample.encoding)
            if conv is None and len(converters) < 256:
                conv = converters[sample.encoding] = json_channel(sample.encoding) or False
            if conv:
                schema, convert = conv
                try:  # before simulated time starts: log time 0 (live, nothing to hold)
                    live.emit_bus(sample.key, schema, convert(sample.payload), t or 0)
                except DecodeError:
                    pass  # counted by the bus's typed subscribers; nothing to show
        if pacer is not None and sample.key == CLOCK:
            pacer.poke()

    return on_raw


def _sim_frames(clock: SimClock, stamper: SimLogTime, pacer: SimPacer,
                outputs: FoxgloveOutputs, sup, refresh, stop: threading.Event, over,
                scene_period: float, supervisor_period: float) -> None:
    """The derived channels on simulated time (module docstring): a scene frame each
    `scene_period` simulated seconds, a supervisor frame each `supervisor_period`, at the
    simulated time the loop gets to them; once a wall second while the clock stands still."""
    scene_due = supervisor_due = 0.0
    restarts = clock.restarts
    last_supervisor = clock.wall()  # the wall the clock counts its stall on
    while not stop.is_set() and not over():
        pacer.wait(POLL)
        if stop.is_set() or not clock.started.is_set():
            continue
        now = clock.now()
        if clock.restarts != restarts:  # a new run: its own time from its first instant
            restarts = pacer.restarts = clock.restarts
            scene_due = supervisor_due = now
        t_ns = stamper()
        if now >= scene_due - EPSILON:
            outputs.scene_frame(t_ns)
            scene_due = next_tick(now, scene_period)
        if sup is not None:
            wall = clock.wall()
            if now >= supervisor_due - EPSILON or (
                    clock.stalled(STALL_EVERY) and wall - last_supervisor >= STALL_EVERY):
                outputs.supervisor_frame(t_ns, sup.snapshot(refresh()))
                supervisor_due = next_tick(now, supervisor_period)
                last_supervisor = wall
        pacer.due = min(scene_due, supervisor_due) if sup is not None else scene_due
