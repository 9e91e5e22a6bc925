"""A central robot's decision logic, as the agent runtime drives it: it decides nothing. It
serves the queue its dispatcher sends (mrta_agent.route.executor: one task after another, in
order) and reports its progress.

* A `Queue` counts only from the dispatcher (a process of the architecture, on the team by its
  process token), addressed to this robot, and newer than the one applied (versions only grow:
  a late or repeated queue changes nothing) — but not too new: a version more than
  VERSION_JUMP ahead counts only once heard again at a later tick (the dispatcher repeats its
  queues every `resend_period`), none above MAX_VERSION (messages.py) — and so does an older
  version than the newest heard: a forged queue repeated under the dispatcher's key at
  MAX_VERSION was applied, and every later queue of the dispatcher's, numbered lower, was
  ignored for good (its robot's tasks never served; the dispatcher cannot number above
  MAX_VERSION); now the dispatcher's repeated queue brings the robot back within two
  `resend_period`s. A late queue is not repeated, so it still changes nothing. What is not
  believed is counted (`Coordinator.refuse`).
* **Lease.** While the dispatcher's token lives but it has been silent for `lease` seconds —
  it is cut off from this robot, and may have given its tasks to others — the robot holds:
  it stands still and keeps its queue until it hears the dispatcher again. When the
  dispatcher's token goes (it crashed), the robot finishes its queue and stops: nothing tells
  it otherwise any more — unless teammates' tokens went with it (within `lease` of it) or
  none is left: then it is this robot that is cut off (a real network cut ends its session, and
  with it every token across the cut), the dispatcher took it for crashed and is granting its
  tasks to others, and the robot holds until it hears its dispatcher again (issue 51: under a
  real TCP cut both sides saw a crash, and the robot finished its queue while its teammates
  served the same tasks). The price: a dispatcher crash within `lease` of a teammate's crash
  looks the same, and the robot holds for good (nobody would plan its tasks anyway). A robot
  that never saw a teammate (a one-robot fleet) cannot tell, and finishes its queue: nobody
  else could serve it.
* **Reports.** A `Progress` at every change (a queue applied, a task set off to, served or left)
  and every `report_period`; and, every `report_period`, one `Queued` per task of its queue
  for the supervisor.
"""

from __future__ import annotations

import logging
from typing import Iterable

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.refusal_tally import MISADDRESSED
from mrta_zenoh.timetext import at

from ..route.executor import PluginReadings, Readings, RouteExecutor
from ..runtime.coordinator import Coordinator, Say
from ..runtime.plugins import Plugins
from .messages import MAX_VERSION, VERSION_JUMP, Queue
from .params import CentralParams

log = logging.getLogger("mrta.central")

VERSION_AHEAD = "version_ahead"            # a queue far ahead, not (yet) heard again
VERSION_BEHIND = "version_behind"          # an older queue than the newest, not (yet) repeated
VERSION_OUT_OF_RANGE = "version_out_of_range"


class CentralCoordinator(Coordinator):
    listens = ("queue",)

    def __init__(self, robot_id: str, params: CentralParams, plugins: Plugins | None = None,
                 dispatcher: str = "dispatcher", readings: Readings | None = None):
        self.robot_id = robot_id
        self.params = params.robot
        self.dispatcher = dispatcher
        self.readings = readings if readings is not None else PluginReadings(
            plugins, params.robot.pose_topic)
        self.route = RouteExecutor()
        self.applied = 0                      # the version of the queue applied
        self.pending: Queue | None = None     # the newest queue heard, applied at the next tick
        # a version far ahead or behind, and when first heard (module docstring)
        self.held: tuple[int, float] | None = None
        self.dispatcher_alive = False
        self.dispatcher_seen = False          # its token was ever seen
        self.teammates: set[str] = set()      # robots of the team whose token lives
        self.team_seen = False                # a teammate's token was ever seen
        self.cut_off = False                  # since the dispatcher's token went (module doc)
        self._went: dict[str, float | None] = {}  # "dispatcher", "teammate": when a token went
        self._gone_told = True
        self.last_word: float | None = None   # when the dispatcher's last queue was heard
        self.holding = False
        self._active: str | None = None
        self._reported: tuple | None = None
        self._report_at: float | None = None

    @property
    def active_task(self) -> str | None:
        return self._active

    def subjects(self, kind: str) -> tuple[str, ...] | None:
        """Only the queues addressed to this robot (`*/central/queue/<robot>`)."""
        return (self.robot_id,) if kind == "queue" else None

    def teammate(self, robot: str, alive: bool) -> None:
        if robot == self.dispatcher:
            self.dispatcher_alive = alive
            self.dispatcher_seen |= alive
            self._gone_told = alive  # told at the next tick, once the team's tokens are known
            if alive:
                self.cut_off = False
                self._went.pop("dispatcher", None)
            else:
                self._went["dispatcher"] = None  # when: the next tick's time
        elif alive:
            self.teammates.add(robot)
            self.team_seen = True
        else:
            self.teammates.discard(robot)
            self._went["teammate"] = None

    def _cut_off(self, now: float) -> bool:
        """Whether this robot is the one cut off (module docstring, Lease): the dispatcher's
        token went and no teammate's is left, or one went within `lease` of it. Once so, until
        the dispatcher's token comes back."""
        for what, when in self._went.items():
            if when is None:
                self._went[what] = now
        gone = self._went.get("dispatcher")
        if self.cut_off or gone is None or not self.dispatcher_seen:
            return self.cut_off
        team = self._went.get("teammate")
        self.cut_off = self.team_seen and (not self.teammates or team is not None and abs(
            team - gone) <= self.params.lease + EPSILON)
        return self.cut_off

    def hear(self, kind: str, sender: str, message, at: float) -> bool:
        if sender != self.dispatcher or not isinstance(message, Queue) \
                or message.robot != self.robot_id:
            self.refuse("queue", sender, MISADDRESSED)
            return False
        if message.version > MAX_VERSION:
            self.refuse("queue", sender, VERSION_OUT_OF_RANGE)
            return True
        newest = self.pending.version if self.pending is not None else self.applied
        ahead = message.version > self.applied + VERSION_JUMP
        if ahead or message.version < newest:
            if self.held is None or self.held[0] != message.version:
                self.held = (message.version, at)
                # behind: a late queue (latency reorders) does it too
                self.refuse("queue", sender, VERSION_AHEAD if ahead else VERSION_BEHIND,
                            forged=ahead)
                return True
            if at <= self.held[1] + EPSILON:
                return True  # the same again at once is no confirmation
            newest = message.version - 1  # confirmed: taken, older or not
        self.held = None
        self.last_word = at if self.last_word is None else max(self.last_word, at)
        if message.version > newest:
            self.pending = message
        return True

    def tick(self, now: float) -> Iterable[Say]:
        changed = False
        if self.pending is not None:
            queue, self.pending = self.pending, None
            self.applied = queue.version
            for change in self.route.assign(queue.tasks, now):
                log.info("%s: left %s (not in queue v%d) %s", self.robot_id, change.task,
                         queue.version, at(now))
            changed = True
        for change in self.route.step(now, self.readings):
            log.info("%s: %s %s %s", self.robot_id, change.kind.replace("_", " "), change.task,
                     at(now))
            changed = True
        cut_off = self._cut_off(now)
        if not self._gone_told and not cut_off:
            self._gone_told = True
            log.warning("%s: the dispatcher is gone: finishing my queue (%s)", self.robot_id,
                        ", ".join(self.route.queue) or "empty")
        holding = cut_off or (self.dispatcher_alive and self.last_word is not None
                              and now - self.last_word > self.params.lease + EPSILON)
        if holding != self.holding:
            self.holding = holding
            log.warning("%s: %s %s", self.robot_id, "the dispatcher is back" if not holding
                        else "cut off (the dispatcher's token went with teammates'): holding"
                        if cut_off else "the dispatcher is silent: holding", at(now))
        self._active = None if holding else self.route.active(now, self.readings)
        return self._report(now, changed)

    def _report(self, now: float, changed: bool) -> list[Say]:
        r = self.route
        pose = self.readings.pose() or (0.0, 0.0, 0.0)
        state = (r.current or "", r.last or "", tuple(r.queue), tuple(r.served_ids()),
                 self.applied, self.holding)
        due = self._report_at is None or now - self._report_at >= \
            self.params.report_period - EPSILON
        if not (changed or due or state != self._reported):
            return []
        out = [r.progress(pose, version=self.applied, holding=self.holding)]
        self._reported = state
        if due:
            self._report_at = now
            out += r.queued(lossy=False)
        return out
