"""`mrta task serve`: the intake as a process of the run (package docstring). The mission runner
starts it when a run is reachable (`mrta demo --rendezvous`) or its instance schedules changes
(a run repeated from its summary); it can also be started by hand beside `mrta sim`.

Why a process of its own, and a lockstep participant: every process of the run must take a
change at the same simulated instant, whatever the network and the machine do, or the run would
not be the one its summary describes. The intake answers each step boundary it is due at
(every PERIOD simulated seconds, the agents' tick) with everything accepted since the last one,
stamped with that instant; lockstep then moves nobody past it before they received the change
(its samples are counted like every participant's). What arrives between two boundaries over the
network — how many requests, in which order — is the machine's; what entered the run, and when,
is recorded (`tasks/change`) and is what a repeated run replays.
"""

from __future__ import annotations

import logging
import math
from collections import deque
import threading
from dataclasses import dataclass, field
from pathlib import Path

from .. import instances
from ..bus import BusOptions
from ..clock import EPSILON
from ..messages import Header
from ..node import Node, NodeTime
from ..refusal_tally import refused_key, tally
from .intake import Intake, Limits
from .messages import ANSWER, CHANGE, HISTORY, INTAKE, REQUEST, Request, answer_key

log = logging.getLogger("mrta.tasks")

PERIOD = 0.1          # simulated s between the step boundaries the intake is due at
TOKEN = f"@mrta/{INTAKE}/intake"  # its liveliness token (up: it takes requests); an `@`
# chunk, so no `**` watch takes it for a robot (the supervisor's robotN/**)
MAX_REFUSED_ANSWERS = 10_000  # refusals answered a step at most (all are counted)
ROLE = INTAKE         # its role in a secured fleet (mrta.secure.roles: `tasks`)


@dataclass(frozen=True)
class ServeOptions:
    instance: Path
    application: str | None = None
    bus_options: BusOptions = field(default_factory=BusOptions)
    sim_time: bool = False
    duration: float | None = None
    limits: Limits = Limits()
    closed: str = ""  # why every submission is refused (Intake's `closed`); "": taken


def intake_for(instance: Path, application: str | None = None,
               limits: Limits = Limits(), closed: str = "") -> Intake:
    """The intake of a run of `instance`: the application's task type checks each submission
    (InstanceKind.admit), the instance's own tasks may be cancelled, its schedule replays."""
    loaded = instances.load(instance, application)
    kind, doc = loaded.kind, loaded.doc
    return Intake(lambda tid, fields: kind.admit(doc, tid, fields), kind.tasks(doc), limits,
                  kind.schedule(doc), closed=closed)


def boundary_after(t: float, scheduled: float | None) -> float:
    """The next instant the intake is due at: the next multiple of PERIOD after `t`, or a
    scheduled change's instant before it."""
    nxt = (math.floor(t / PERIOD + EPSILON) + 1) * PERIOD
    if scheduled is not None and t + EPSILON < scheduled < nxt - EPSILON:
        return scheduled
    return round(nxt, 9)


def serve(options: ServeOptions, stop: threading.Event | None = None) -> int:
    intake = intake_for(options.instance, options.application, options.limits, options.closed)
    time = NodeTime.LOCKSTEP if options.sim_time else NodeTime.WALL
    with Node(options.bus_options, ROLE, name=INTAKE, time=time, stop=stop) as node:
        bus, clock = node.bus, node.clock

        # refusals are answered from the loop, not the network's thread (a publish there may
        # wait on a slow submitter), and at most MAX_REFUSED_ANSWERS a step: a flood's
        # refusals are all counted (the tally), its oldest beyond that go unanswered
        refused: deque = deque(maxlen=MAX_REFUSED_ANSWERS)

        def on_request(sample) -> None:
            submitter = sample.key.rsplit("/", 1)[-1]
            req: Request = sample.message
            if req.header.frame_id != submitter:
                answer = intake.refuse_mismatch(submitter, req, f"its header names "
                                              f"{req.header.frame_id[:40]!r}")
            else:
                answer = intake.offer(submitter, req)
            if answer is not None:
                refused.append((submitter, answer))

        node.hold(bus.subscribe(f"{REQUEST}/*", on_request, msg_type=Request))
        node.hold(bus.answer_queries(HISTORY, intake.history))  # a view started late asks
        node.declare_alive(TOKEN)
        log.info("tasks: taking requests on %s/<submitter> (%d tasks in the instance)", REQUEST,
                 len(intake.tasks))
        if not node.wait_for_clock():
            return 0
        t, said = clock.now(), 0
        while not node.stop.is_set():
            nxt = boundary_after(t, intake.next_scheduled())
            if options.duration is not None and nxt > options.duration + EPSILON:
                break
            if not clock.sleep_until(nxt, node.stop):
                break
            t = clock.now()
            answers, changes = intake.release(t)
            for change in changes:
                bus.publish(CHANGE, change)
            while refused:
                answers.append(refused.popleft())
            for submitter, answer in answers:
                bus.publish(answer_key(submitter), answer)
            counts = intake.refused()
            if sum(counts.values()) != said:  # what it refused, for the summary
                said = sum(counts.values())
                bus.publish(refused_key(INTAKE), tally(Header(INTAKE, t, 0), counts))
    return 0


def secure_role() -> dict[str, list[str]]:
    """What the intake may do in a secured fleet (mrta.secure.roles `tasks`): say what entered
    the run, answer every submitter, say what it refused, and take part in lockstep."""
    from ..lockstep.protocol import DONE, PARTICIPANT
    return {"publish": [CHANGE, HISTORY, f"{ANSWER}/*", refused_key(INTAKE), f"{DONE}/{INTAKE}"],
            "tokens": [TOKEN, f"{PARTICIPANT}/{INTAKE}"]}
