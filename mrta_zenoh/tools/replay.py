"""Republish a recording onto the bus with its original timing (rosbag play): `mrta replay`.

Bus channels go out on their keys with their Zenoh encodings, liveliness changes as tokens
declared and undeclared again, so `mrta supervise`, `mrta echo` and `mrta view` work on a past
run exactly as on a live one. The simulated clock is left out unless asked (`clock=True`): a
replay then runs on the wall clock of whoever watches, or on its own recorded time.

Timing follows the recording's log times (mrta_zenoh.recording): a wall-time recording (`mrta
record`) replays at the pace it was recorded; a simulated-time one (the mission runner's, `mrta
view --sim-time`) at the simulated pace — a 60 s mission recorded at `--speed 0` in 2 s replays
in 60 s at `--speed 1`, in 6 s at `--speed 10` — its simulator restarts 1 s apart. A replay that
falls behind (a loaded machine, a heavy recording) by more than MAX_LAG seconds of the
recording slips instead of catching up in a burst: the pace between samples stays the
recording's, and the clock never runs faster than the speed the replay announces.

With `clock=True` the replay is the clock source, as a simulator is (docs/architecture.md, "The
clock"): each recorded run is announced under a new run id naming the speed at which the replay
moves its simulated time (`clock.run_id`) — the replay's `--speed` for a simulated-time
recording, the recorded run's speed times it for a wall-time one — and holds
`@mrta/clock_source/<run id>` while it plays that run. A follower's creep bound (SimClock) then
trusts the replay at its own pace, not at the recorded run's, and sees the run end when the
replay is over (`mrta supervise --sim-time --duration N` stops there).

A recording is input like any other, and may be crafted (a topic `a//b`, a liveliness
payload `[1]`, log times 0 and 2⁶⁴−1 would make tracebacks or a 31-year wait). So the
plan (`plan_replay`) is made before any session opens, and:

* a record whose topic is not a concrete key Zenoh accepts (an empty chunk, a wildcard, a
  character keys may not hold), or a liveliness record whose payload is not `{"alive": bool}`,
  is skipped and counted, with one warning naming how many and the first of them;
* a silence between two records longer than `max_gap` seconds (default MAX_GAP, a minute of
  the recording's time) is shortened to `max_gap`, and the replay says how many it shortened:
  nothing a recorder writes has such gaps but a run left idle, which plays the same shortened.
"""

from __future__ import annotations

import json
import logging
import os
import threading
import time
from collections import Counter
from dataclasses import dataclass, field, replace
from pathlib import Path

from .. import codec
from ..bus import Bus, BusOptions, open_bus
from ..clock import run_id, run_speed
from ..errors import ConfigError
from ..messages import Clock
from ..yamlfile import plural
from ..keys import (CLOCK, CLOCK_SOURCE_ENDED, CLOCK_SOURCE_TOKEN, LIVELINESS_PREFIX, matches,
                    validate_key_expr)
from ..lifecycle import stop_on_signals
from ..limits import RUN_DURATION
from ..recording import Record, read_recording
from ..lifecycle import wait_for_stop

log = logging.getLogger("mrta.replay")

MAX_GAP = 60.0  # seconds of the recording: the longest silence replayed as it was
MAX_LAG = 1.0   # seconds of the recording a replay may fall behind before it slips
# Wall seconds a replay keeps its session open after its last put. Closing a session drops
# what its queues (and the listeners' socket buffers) still hold — a recorder beside a replay
# at --speed 0 of 20,000 samples received 5,918 — and zenoh-python offers no flush and no
# delivery confirmation from a plain subscriber, so the replay lingers: a listener keeping
# up at a tenth of its idle rate (≈ 30 µs a sample) drains a 20,000-sample backlog in it.
DRAIN = 2.0
NS = 1_000_000_000
# Wall seconds a replay pauses once it has announced a recorded run's end. The run's processes
# stopped after its simulator did, so their tokens' losses are recorded at the run's last
# instant: sent at once after the end, a follower (`mrta supervise --sim-time`) sometimes
# handled robot1's first and showed a robot that ran to the end offline with
# `communication_lost` (issue 51, the newcomer's list). A live run gives the end that time.
END_SETTLE = 1.0


@dataclass(frozen=True)
class Step:
    """One thing to do `at` seconds (recording time, gaps shortened) after the first record:
    publish a sample, or declare (`alive` True) / undeclare a token."""

    at: float
    key: str
    encoding: str = ""
    payload: bytes = b""
    alive: bool | None = None  # None: a sample; True/False: a token up / down
    settle: float = 0.0  # wall seconds to wait once it is done (a run's end: END_SETTLE)


@dataclass
class Plan:
    steps: list[Step] = field(default_factory=list)
    skipped: Counter = field(default_factory=Counter)  # reason → records skipped
    first_skipped: dict[str, str] = field(default_factory=dict)  # reason → the first topic
    shortened: int = 0  # gaps longer than max_gap
    span: float = 0.0  # seconds the plan takes at speed 1


def concrete_key_problem(key: str) -> str | None:
    """Why `key` cannot be published on (or held as a token) as it is, or None: it must be a
    valid key expression (keys.validate_key_expr, as the bus checks every key) with no wildcard
    (`*`, `**`, `$*`): a crafted `**` would reach every subscriber at once."""
    try:
        validate_key_expr(key)
    except ConfigError as exc:
        return exc.detail
    if any(c in ("*", "**") or "$*" in c for c in key.split("/")):
        return f"key {key!r:.80} is a wildcard expression, not a key"
    return None


def _alive(payload: bytes) -> bool | None:
    """The `alive` flag of a recorded liveliness change, or None if the payload is not
    `{"alive": true|false}`."""
    try:
        value = json.loads(payload)
    except (ValueError, UnicodeDecodeError):  # JSONDecodeError is a ValueError
        return None
    alive = value.get("alive") if isinstance(value, dict) else None
    return alive if isinstance(alive, bool) else None


def plan_replay(records: list[Record], key_expr: str = "**", clock: bool = False,
                max_gap: float = MAX_GAP) -> Plan:
    """What replaying `records` (in log-time order) does and when; pure, so hostile files are
    tested without a bus or a clock."""
    plan = Plan()
    problems: dict[str, str | None] = {}  # memo: keys repeat

    def skip(reason: str, key: str) -> None:
        plan.skipped[reason] += 1
        plan.first_skipped.setdefault(reason, key)

    at, last_t = 0.0, None
    for key, encoding, t, payload in records:
        if last_t is not None:
            gap = max(0, t - last_t) / NS
            if gap > max_gap:
                gap = max_gap
                plan.shortened += 1
            at += gap
        last_t = t
        token = key.startswith(LIVELINESS_PREFIX)
        target = key[len(LIVELINESS_PREFIX):] if token else key
        if target not in problems:
            problems[target] = concrete_key_problem(target)
        if problems[target] is not None:
            skip("not a concrete key", key)
            continue
        if not matches(key_expr, target) or (not token and key == CLOCK and not clock):
            continue
        if token:
            alive = _alive(payload)
            if alive is None:
                skip('liveliness payload is not {"alive": true|false}', key)
                continue
            plan.steps.append(Step(at, target, alive=alive))
        else:
            plan.steps.append(Step(at, target, encoding, payload))
    plan.span = at
    return plan


def announce_runs(plan: Plan, speed: float, simulated: bool) -> Plan:
    """The plan, replayed at `speed`, with every recorded run's clock samples renamed to a new
    run id announcing the pace at which the replay moves that run's time (`_pace`), and its
    `@mrta/clock_source/<id>` token held from the run's first sample to its last. A clock
    sample that does not decode goes out as recorded: its followers reject it, as they would
    have then."""
    ids: dict[str, str] = {}
    last: dict[str, int] = {}  # new id → index of its last sample in `steps`
    steps: list[Step] = []
    for step in plan.steps:
        if step.alive is not None or step.key != CLOCK:
            steps.append(step)
            continue
        try:
            msg = codec.decode(Clock.TYPE_NAME, step.payload)
        except codec.DecodeError:
            steps.append(step)
            continue
        new = ids.get(msg.source)
        if new is None:
            new = ids[msg.source] = _run_id(_pace(msg.source, speed, simulated))
            steps.append(Step(step.at, f"{CLOCK_SOURCE_TOKEN}/{new}", alive=True))
        steps.append(replace(step, payload=codec.encode(Clock(msg.stamp, new))))
        last[new] = len(steps) - 1
    for new, i in sorted(last.items(), key=lambda kv: -kv[1]):  # from the end: indexes hold
        # the run's end announced before its token goes: its followers see an end, not a death
        ended = f"{CLOCK_SOURCE_TOKEN}/{new}/{CLOCK_SOURCE_ENDED}"
        steps[i + 1:i + 1] = [Step(steps[i].at, ended, alive=True),
                              Step(steps[i].at, f"{CLOCK_SOURCE_TOKEN}/{new}", alive=False),
                              Step(steps[i].at, ended, alive=False, settle=END_SETTLE)]
    plan.steps = steps
    return plan


def _pace(source: str, speed: float, simulated: bool) -> float | None:
    """Simulated seconds per wall second a replay at `speed` moves the recorded run `source`
    (0: as fast as possible): `speed` itself for a simulated-time recording; for a wall-time
    one, the recorded run's speed times it — None when that run announced none."""
    if simulated:
        return speed
    recorded = run_speed(source)
    if recorded is None:
        return None
    return 0.0 if recorded == 0 or speed == 0 else recorded * speed


def _run_id(pace: float | None) -> str:
    return run_id(pace) if pace is not None else os.urandom(6).hex()


def execute(plan: Plan, bus: Bus, speed: float, stop: threading.Event) -> int:
    """Carry out `plan` on `bus` at `speed` (0: as fast as possible) until done or `stop`;
    returns how many samples went out. Tokens declared here are closed before returning."""
    sent = 0
    tokens = {}
    wall0 = time.monotonic()
    try:
        for step in plan.steps:
            if stop.is_set():
                break
            if speed > 0:
                ahead = step.at / speed - (time.monotonic() - wall0)
                if ahead > 0 and wait_for_stop(stop, ahead):
                    break
                if ahead < -MAX_LAG / speed:  # fallen behind: slip, never a burst
                    wall0 += -ahead - MAX_LAG / speed
            if step.alive is None:
                bus.publish_raw(step.key, step.encoding, step.payload)
                sent += 1
            elif step.alive and step.key not in tokens:
                tokens[step.key] = bus.declare_token(step.key)
            elif not step.alive and step.key in tokens:
                tokens.pop(step.key).close()
            if step.settle and wait_for_stop(stop, step.settle):
                break
    finally:
        for tok in tokens.values():
            tok.close()
    return sent


def run_replay(*, recording: Path, bus_options: BusOptions, speed: float = 1.0,
               key_expr: str = "**", clock: bool = False, max_gap: float = MAX_GAP,
               stop: threading.Event | None = None, bus: Bus | None = None) -> int:
    """Publish every recorded sample (matching `key_expr`) at its recorded pace × `speed`
    (0: as fast as possible), silences longer than `max_gap` s shortened to it; returns how
    many samples went out. Everything is checked and planned before a session opens; a session
    of its own is closed DRAIN seconds after the last put (or at once on `stop`). `bus`: an
    open bus to use instead of opening one (tests: the in-process bus); it is left open."""
    validate_key_expr(key_expr)
    if speed < 0:
        raise ConfigError(f"--speed must be ≥ 0, got {speed}")
    if RUN_DURATION.problem(max_gap):
        raise ConfigError(f"--max-gap {RUN_DURATION.problem(max_gap)}")
    records = read_recording(recording)
    if not records:
        raise ConfigError("the recording holds no bus channel", file=str(recording))
    plan = plan_replay(records, key_expr, clock, max_gap)
    if clock:
        announce_runs(plan, speed, records.log_time == "simulated")
    for reason, n in plan.skipped.items():
        log.warning("%s: skipped %d records: %s (first: %r)", recording, n, reason,
                    plan.first_skipped[reason][:120])
    if plan.shortened:
        log.warning("%s: shortened %d silences longer than %g s to %g s", recording,
                    plan.shortened, max_gap, max_gap)
    if records.log_time == "simulated":
        log.info("%s is in simulated time: replaying %.1f simulated s at %s× the simulated pace",
                 recording, plan.span, speed or "∞")
    with stop_on_signals(stop) as stop:
        if bus is not None:
            sent = execute(plan, bus, speed, stop)
        else:
            with open_bus(bus_options) as own:
                wait_for_stop(stop, 0.5)  # subscribers already running are reached (discovery)
                sent = execute(plan, own, speed, stop)
                wait_for_stop(stop, DRAIN)  # what is queued leaves before the session closes
    log.info("replayed %s from %s", plural(sent, "sample"), recording)
    return sent
