"""SSI for one robot, as pure logic on an injected time (like MURDOCH's auction.Murdoch):
messages heard go in through `hear`, teammates through `teammate`, and `tick(now)` returns what
to send (the runtime's `Say`; the hooks are `RouteLogic`'s). No bus, no clock, no threads.

The auction (Lagoudakis et al. 2005; Koenig, Tovey et al. 2006; docs/ssi.md):

* **A round.** Every robot bids on its best open task: the one whose cheapest insertion into its
  own path adds the least travel time (the MinSum rule; `minsum_insertion`, no re-ordering of
  the rest). The lowest bid wins that one task, which the winner inserts there. Ties: the lower
  robot id, then the lower task id, then the earlier place. A robot bids only on tasks it has
  the capability for; one with nothing to bid on says so (task −1).
* **Priority** (tasks submitted at run time, issue 50 — not in the papers, whose tasks are
  all alike): a robot bids on its cheapest task among the open ones of the highest priority
  it can serve, and the auctioneer awards the highest-priority bid, then the lowest; so a
  more urgent task is awarded before any less urgent one still open — and served before
  them: a robot inserts a task only among its path's tasks of the same priority, after every
  more urgent one and before every less urgent one (`places`), and bids that insertion's cost
  (an urgent task awarded to a robot with a long path was inserted where it added least, at
  its end, and served last). The instance's tasks are all priority 0: with no priority
  given, the auction is the paper's.
* **Rounds** go on while some open task has a bidder. A task that arrives (is known from
  `lookahead` seconds before its arrival) opens at the next round; the unserved tasks of a
  robot that leaves the team (its token goes) are opened again; a served task is DONE for good.
* **Who clears.** The lowest-id live robot is the auctioneer: it opens each round with a Round
  (every task's state), waits for a Bid from every live teammate for that round — and, for
  `join_wait` seconds after its first tick, from every robot of the instance not known gone —
  awards the best, and opens the next round. Every Round is answered, with a bid or with "no
  bid" (task −1), which is also its acknowledgement: the auctioneer repeats a Round every
  `resend_period` until every robot it waits for has answered it (the last one too, so nobody
  misses an award), and answers a bid for an earlier round with its current Round; a bidder
  answers each Round it hears (only the auctioneer keeps time) and repeats only the report of
  tasks it served until a Round shows them DONE. When the auctioneer goes, the next lowest id
  takes over from the last Round it heard, opening a new round (docs/ssi.md says why one
  auctioneer and what a takeover can lose).

**What a message is believed for** (docs/security.md). A Round counts only from the auctioneer
this robot follows, and only with a number it can have reached: the same round again, a later one
by at most ROUND_JUMP, or — a number far ahead, or behind the last one it adopted from that
auctioneer — the same number heard again at least half a `resend_period` later (the auctioneer
repeats a Round until every robot answered it, so a real one is always confirmed; a forged
`Round` numbered 2^62 said once is not). A Round under the auctioneer's key that the auctioneer
never sent — the same number or one a little ahead, saying every task DONE — was adopted and,
once the auction was over, emptied every path for good (the auctioneer, with every bid in,
had nothing to repeat): each Bid now says which Round it answers (`seen`, its digest), and the
auctioneer counts a bid for a round, or a content, it never sent (`round_not_sent`) and repeats
its own Round until that bidder answers it — one forged Round costs at most two
`resend_period`s. A Bid's `served` counts only for tasks the bidder held
(owned, or was awarded — or shown held by a Round of another robot leading a team apart: when
the auctioneer stood still long enough for its teammates to count it stalled, the next id led
them, and its awards were served before they came back to this auctioneer, which never made
them; w23's TeSSI on C109 refused 200 honest reports as forged. Shown only by the bidder's
own Round, it is refused but not counted forged: an honest split looks the same); a bid for a task its bidder cannot serve, or at a negative cost, is
refused whole. What is not believed is counted by kind, sender and reason (`refused`).

**A robot that does not answer.** A round waits for the bids of the robots expected — but not
for ever: a robot that has not answered the round for `silence` seconds since it opened is
left out of it and its unserved tasks are opened again, as if its token had gone (a dead robot
whose token a forger keeps alive, a certified robot that never bids); it is back when it bids.

**Decision time.** Each award records its computation time (`Round.ms`): the slowest bid of its
round (each bidder times its own `best_bid` and says so in its `Bid`; the bidders compute side by
side, so the slowest one gates the round) plus the auctioneer's winner determination. It is wall
time (`timer`, `time.perf_counter` by default) even in lockstep, where simulated time stands still
while the logic computes: a computation time is the machine's, a measurement that never enters a
decision.
"""

from __future__ import annotations

import collections
import logging
import math
import time
from typing import Callable, NamedTuple

import msgspec

from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.insertion import Origin, minsum_insertion, ranks
from mrta_zenoh import timetext
from mrta_zenoh.refusal_tally import MALFORMED

from ..route.own_route import RouteLogic
from ..runtime.coordinator import Say
from .messages import DONE, OPEN, UNKNOWN, Bid, Round, digest

log = logging.getLogger("mrta.ssi")

TASKS_LEEWAY = 100_000  # tasks a Round may count beyond this robot's (the intake's bound)
ROUND_JUMP = 64  # rounds ahead of the last adopted a Round is believed at once (module docstring)
# why a message, or a claim in it, was not believed (`Ssi.refused`)
NOT_AUCTIONEER = "not_auctioneer"  # a Round from another robot (a takeover does it too)
ROUND_AHEAD = "round_ahead"        # a round far ahead, not (yet) confirmed
ROUND_BEHIND = "round_behind"      # an older round (late, or the auctioneer is behind)
NOT_HELD = "not_held"              # served a task it never held
CANNOT_SERVE = "cannot_serve"      # a bid for a task it cannot serve
NEGATIVE_COST = "negative_cost"
ROUND_NOT_SENT = "round_not_sent"  # a bid answering a Round its auctioneer never sent
TASKS_AHEAD = "tasks_ahead"        # a Round counting tasks submitted that this robot has not
                                   # taken yet (out of lockstep: the change reaches it later)
NEGATIVE = -1e-9  # a cost below this is negative (an insertion's cost is ≥ 0 but for rounding)


class Award(NamedTuple):
    round: int
    task: int
    robot: int
    cost: float
    ms: float = 0.0  # its computation time (module docstring, "Decision time")


class Ssi(RouteLogic):
    """One robot's SSI. `problem` is the instance every robot reads; a task is known from
    `lookahead` seconds before its arrival (math.inf: all from the start); `resend_period`: how
    often a Round still missing bids, or an unacknowledged report of served tasks, is
    repeated; `join_wait`: how long the first auctioneer waits for robots of the instance it
    has not seen yet; `origin`: where and when this robot's path begins; `timer`: the wall
    clock (seconds) decision times are measured with."""

    listens = ("round", "bid")  # a bid goes to its auctioneer's sub-key

    def __init__(self, problem: Problem, robot_id: str, *, lookahead: float = 0.0,
                 resend_period: float = 0.5, join_wait: float = 1.0, origin: Origin = Origin(),
                 timer: Callable[[], float] = time.perf_counter, silence: float = math.inf):
        self.problem = problem
        self.id = robot_id
        self.i = problem.robot_index(robot_id)
        self.index = {r.id: k for k, r in enumerate(problem.robots)}  # robot id → its index
        self.lookahead, self.resend_period, self.join_wait = lookahead, resend_period, join_wait
        self.timer = timer
        self.rank = ranks([r.id for r in problem.robots])
        self.task_rank = ranks([t.id for t in problem.tasks])
        self.alive: set[int] = set()      # teammates whose token lives
        self.gone: set[int] = set()       # teammates whose token went
        # the shared state, as the last Round heard (or made) says
        self.round = 0
        self.round_from: int | None = None
        self.owners = [UNKNOWN] * len(problem.tasks)
        self.awards: list[Award] = []
        # this robot's own path
        self.path: list[int] = []
        self.origin = origin
        self.unacked: set[int] = set()    # served, not yet DONE in a Round heard
        self.answer_due = False           # a Round heard, not answered yet
        self.last_bid = -math.inf
        # the auctioneer's side
        self.leading = False
        self.started: float | None = None
        self.bids: dict[int, tuple[int, float]] = {}
        self.bid_ms: dict[int, float] = {}  # how long each bid of the round took to compute
        self.reported: set[int] = set()   # served tasks heard of, to show DONE
        self.lagging = False
        self.last_round = -math.inf
        # what is believed (module docstring): a round number held until confirmed, when each
        # robot last answered, since when the current round waits, who it no longer waits for
        self.silence = silence
        self.held: tuple[int, float] | None = None
        self.answered: dict[int, float] = {}
        self.asked_at = -math.inf
        self.silent: dict[int, float] = {}  # robot → since when the rounds leave it out
        self.out_said: tuple[str, ...] = ()  # who the last Round said it leaves out (`out`)
        self.seen: int | None = None  # the digest of the Round adopted last (Bid.seen)
        self.said: tuple[int, set[int]] = (0, set())  # the round led, the digests it sent
        self.round_wall = -math.inf  # the wall time (`timer`) it first sent that round
        self.refused: collections.Counter[tuple[str, str, str, bool]] = collections.Counter()
        # (robot, task) → the robots whose Rounds, not this robot's auctioneer's, showed that
        # robot holding that task (a team apart: module docstring, "What a message is believed")
        self.shown: dict[tuple[int, int], set[int]] = {}
        # tasks submitted at run time (tasks_added): their indices follow the instance's; a
        # task's priority when not 0 (higher first: `best_bid`, the award, `places`)
        self.base = len(problem.tasks)
        self.priority: dict[int, int] = {}

    # ------------------------------------------------------------------ tasks at run time
    def tasks_added(self, growth, now: float) -> None:
        """Tasks submitted at run time (runtime/growth.py), in the order they entered: the
        problem grows by them (every robot's the same way, at the same tick), each UNKNOWN
        until the auctioneer opens it at its next round, as an arrival (`_lead`)."""
        self.problem = growth.problem(self.problem)
        self.owners = list(self.owners) + [UNKNOWN] * (len(self.problem.tasks) - len(self.owners))
        self.task_rank = ranks([t.id for t in self.problem.tasks])
        for task in growth.tasks:
            self._prioritise(self.problem.task_index(task.id), task.priority)

    def task_priority(self, task_id: str, priority: int, now: float) -> None:
        try:
            self._prioritise(self.problem.task_index(task_id), priority)
        except KeyError:
            pass  # a task this robot was never told of: nothing to order

    def _prioritise(self, j: int, priority: int) -> None:
        """Only priorities other than 0 are kept (`places`: none kept, the paper's auction)."""
        if priority:
            self.priority[j] = priority
        else:
            self.priority.pop(j, None)

    def urgency(self, j: int) -> int:
        """How task j ranks before cost (higher first): its priority, 0 unless given."""
        return self.priority.get(j, 0)

    # ------------------------------------------------------------------ what it tells the runtime
    @property
    def active_task(self) -> str | None:
        return self.problem.tasks[self.path[0]].id if self.path else None

    def route(self) -> list[str]:
        return [self.problem.tasks[j].id for j in self.path]

    def winners(self) -> dict[str, str]:
        """Task id → the robot it was awarded to (served ones included), as this robot knows."""
        p = self.problem
        return {p.tasks[j].id: p.robots[w].id for j, w in enumerate(self.owners) if w >= 0}

    def auctioneer(self) -> int:
        """The lowest-id robot among the live teammates and this one."""
        return min(self.alive | {self.i}, key=lambda k: self.rank[k])

    # ------------------------------------------------------------------ what was heard
    def teammate(self, robot: str, alive: bool) -> None:
        k = self.index.get(robot)
        if k is None or k == self.i:
            return
        if alive:
            self.alive.add(k)
            self.gone.discard(k)
        else:
            self.alive.discard(k)
            self.gone.add(k)

    def hear(self, kind: str, sender: str, msg: Round | Bid, at: float) -> bool:
        """Take a teammate's Round or Bid; False when it is malformed (an index outside the
        instance) and was dropped whole."""
        k = self.index.get(sender)
        if k is None:
            return False
        if k == self.i:
            return False
        if kind == "round" and isinstance(msg, Round):
            return self._on_round(k, msg, at)
        if kind == "bid" and isinstance(msg, Bid):
            return self._on_bid(k, msg, at)
        return False

    def _on_round(self, k: int, msg: Round, heard: float) -> bool:
        n_robots, n_tasks = len(self.problem.robots), len(self.problem.tasks)
        if (not self.base <= len(msg.owners) <= n_tasks + TASKS_LEEWAY
                or not all(DONE <= w < n_robots for w in msg.owners)
                or not -1 <= msg.award < len(msg.owners)):
            self.refused[("round", self.problem.robots[k].id, MALFORMED, True)] += 1
            return False
        sender = self.problem.robots[k].id
        if len(msg.owners) > n_tasks:  # tasks this robot has not taken yet: not now
            self.refused[("round", sender, TASKS_AHEAD, False)] += 1
            return True
        seen = digest(msg.owners)
        if len(msg.owners) < n_tasks:  # made before tasks that entered since: not yet opened
            msg = msgspec.structs.replace(
                msg, owners=tuple(msg.owners) + (UNKNOWN,) * (n_tasks - len(msg.owners)))
        if k != self.auctioneer():
            self.refused[("round", sender, NOT_AUCTIONEER, False)] += 1
            for j, w in enumerate(msg.owners):  # who it shows holding what (module docstring)
                if w >= 0:
                    self.shown.setdefault((w, j), set()).add(k)
            return True  # not (or no longer) the auctioneer this robot follows
        behind = k == self.round_from and msg.round < self.round
        if behind or msg.round > self.round + ROUND_JUMP:
            if self.held is None or self.held[0] != msg.round:
                self.held = (msg.round, heard)
                self.refused[("round", sender, ROUND_BEHIND if behind else ROUND_AHEAD,
                              not behind)] += 1
                return True  # an older Round delivered late, or one far ahead: not yet
            if heard - self.held[1] < self.resend_period / 2:
                return True  # the same again at once is no confirmation
        self.held = None
        self._adopt(k, msg.round, list(msg.owners), msg.award, msg.cost, msg.ms)
        self.seen, self.answer_due = seen, True
        return True

    def _on_bid(self, k: int, msg: Bid, heard: float) -> bool:
        n_tasks = len(self.problem.tasks)
        if (not -1 <= msg.task < n_tasks or not all(0 <= j < n_tasks for j in msg.served)
                or msg.ms < 0):
            self.refused[("bid", self.problem.robots[k].id, MALFORMED, True)] += 1
            return False
        if msg.auctioneer != self.id:
            return True
        sender = self.problem.robots[k].id
        if msg.cost < NEGATIVE or (msg.task >= 0 and not self.problem.capable(k, msg.task)):
            self.refused[("bid", sender, NEGATIVE_COST if msg.cost < NEGATIVE else CANNOT_SERVE,
                          True)] += 1
            return True  # refused whole: it is no answer either
        self.answered[k] = heard
        held = {a.task for a in self.awards if a.robot == k}
        for j in msg.served:
            shown = self.shown.get((k, j), set())  # by Rounds of a team apart (docstring)
            if self.owners[j] in (k, DONE) or j in held or shown - {k}:
                self.reported.add(j)
            else:
                self.refused[("bid", sender, NOT_HELD, not shown)] += 1
        if not self.leading:
            return True
        if msg.round > self.round or (msg.round == self.round and msg.seen is not None
                                      and msg.seen not in self.said[1]):
            # it follows a Round in this auctioneer's name that it never sent: count it, and
            # repeat the real one until that bidder answers it (module docstring)
            self.refused[("bid", sender, ROUND_NOT_SENT, False)] += 1
            self.bids.pop(k, None)
            self.lagging = True
        elif msg.round < self.round:
            self.lagging = True  # it missed the current Round: send it again
        else:
            self.bids[k] = (msg.task, msg.cost)
            # a bidder's own measurement, believed up to the wall time since the round went
            # out (a forged 1e300 became the run's decision time)
            self.bid_ms[k] = min(msg.ms, (self.timer() - self.round_wall) * 1000.0)
        return True

    def served(self, task_id: str, at: float) -> None:
        """This robot finished serving `task_id` at `at`: it leaves the path, which now begins
        there and then, and the auctioneer is told until its Rounds show it DONE."""
        j = self.problem.task_index(task_id)
        if j in self.path:
            self.path.remove(j)
        self.origin = Origin(j, at)
        self.unacked.add(j)
        self.reported.add(j)

    # ------------------------------------------------------------------ the shared state
    def _adopt(self, announcer: int, number: int, owners: list[int], award: int,
               cost: float, ms: float = 0.0) -> None:
        """Take a Round: tasks no longer this robot's leave its path; tasks newly its own go in
        at their cheapest place — the round's award first, any other (a Round missed) in task
        id order."""
        mine = {j for j, w in enumerate(owners) if w == self.i}
        self.path = [j for j in self.path if j in mine]
        new = sorted(mine - set(self.path) - self.unacked - {award},
                     key=lambda j: self.task_rank[j])
        if award in mine and award not in self.path and award not in self.unacked:
            new.insert(0, award)
        for j in new:
            _, where = self.insertion(j)
            self.path.insert(where, j)
        if award >= 0 and owners[award] >= 0 and (not self.awards
                                                  or self.awards[-1].round != number):
            self.awards.append(Award(number, award, owners[award], cost, ms))
        self.round, self.round_from, self.owners = number, announcer, owners
        self.unacked = {j for j in self.unacked if owners[j] != DONE}

    def insertion(self, j: int) -> tuple[float, int]:
        """(cost, place) of task j at its best place in this robot's path: SSI's MinSum rule
        (the added travel time; under hard windows only where every window holds, the path
        timed from its origin: planning.insertion); a subclass bidding another rule (TeSSI's
        temporal network) overrides it. An infinite cost where j fits nowhere — not bid on,
        and an award of it goes at the end of the path."""
        return minsum_insertion(self.problem, self.i, self.path, j, *self.origin,
                                places=self.places(j))

    def places(self, j: int) -> range | None:
        """Where task j may go in this robot's path (module docstring, "Priority"): after its
        last more urgent task, before its first less urgent one after that; None — anywhere
        (no task of the run has a priority)."""
        if not self.priority:
            return None
        p = self.urgency(j)
        urgency = [self.urgency(k) for k in self.path]
        lo = max((n + 1 for n, q in enumerate(urgency) if q > p), default=0)
        hi = next((n for n in range(lo, len(urgency)) if urgency[n] < p), len(urgency))
        return range(lo, hi + 1)

    def best_bid(self) -> tuple[int, float]:
        """(task, added travel time) of this robot's cheapest open task among the most urgent
        it can bid on (`urgency`: a task submitted at run time with a priority above the rest is
        bid on, and awarded, first); (−1, 0) if none."""
        best = None
        for j, w in enumerate(self.owners):
            if w != OPEN or not self.problem.capable(self.i, j):
                continue
            cost, _ = self.insertion(j)
            if not math.isfinite(cost):
                continue
            if best is None or (-self.urgency(j), cost, self.task_rank[j]) < \
                    (-self.urgency(best[0]), best[1], self.task_rank[best[0]]):
                best = (j, cost)
        return best if best is not None else (-1, 0.0)

    # ------------------------------------------------------------------ one tick
    def tick(self, now: float) -> list[Say]:
        if self.started is None:
            self.started = now
        out: list[Say] = []
        if self.auctioneer() == self.i:
            out += self._lead(now)
        else:
            self.leading = False
        out += self._bid(now)
        return out

    def _expected(self, now: float) -> set[int]:
        """Whose bids a round waits for: the live teammates and this robot; during `join_wait`
        also every robot of the instance not known to have gone."""
        if now < self.started + self.join_wait:
            return set(range(len(self.problem.robots))) - self.gone - set(self.silent)
        return (self.alive - set(self.silent)) | {self.i}

    def _judge_silence(self, now: float) -> None:
        """Who the round no longer waits for, and who is back (module docstring)."""
        for k in sorted(self.alive | set(self.silent)):
            answered = self.answered.get(k, -math.inf)
            if k in self.silent:
                if answered > self.silent[k] or k not in self.alive:
                    del self.silent[k]  # it answered again (or its token went: gone anyway)
                    log.warning("%s: %s answers again %s", self.id, self.problem.robots[k].id,
                                timetext.at(now))
            elif answered < self.asked_at and now - self.asked_at > self.silence:
                self.silent[k] = now
                log.warning("%s: %s has not answered round %d for %g s: left out, its tasks "
                            "opened again %s", self.id, self.problem.robots[k].id, self.round,
                            self.silence, timetext.at(now))

    def _lead(self, now: float) -> list[Say]:
        owners = list(self.owners)
        reopened = not self.leading  # a new auctioneer opens a round of its own
        self.leading = True
        acked = False
        for j in self.reported:
            if owners[j] != DONE:
                owners[j], acked = DONE, True
        self.reported = set()
        self._judge_silence(now)
        out = self.out()
        present = self.alive - set(self.silent)
        for j, task in enumerate(self.problem.tasks):
            if owners[j] == UNKNOWN and task.arrival <= now + self.lookahead:
                owners[j], reopened = OPEN, True
            elif owners[j] >= 0 and owners[j] != self.i and owners[j] not in present:
                owners[j], reopened = OPEN, True  # its robot left before serving it
        award, cost, ms = -1, 0.0, 0.0
        began = self.timer()
        self.bids[self.i] = self.best_bid()
        self.bid_ms[self.i] = (self.timer() - began) * 1000.0
        expected = self._expected(now)
        missing = expected - self.bids.keys()  # a bid is also the Round's acknowledgement
        if not reopened and OPEN in owners and not missing:
            # a bid from a robot that left meanwhile does not count
            began = self.timer()
            best = min(((-self.urgency(j), c, self.rank[r], self.task_rank[j], r, j)
                        for r, (j, c) in self.bids.items()
                        if r in expected and j >= 0 and owners[j] == OPEN), default=None)
            if best is not None:
                _, cost, _, _, winner, award = best
                owners[award] = winner
                ms = (max(self.bid_ms.get(r, 0.0) for r in self.bids if r in expected)
                      + (self.timer() - began) * 1000.0)
        if reopened or award >= 0:
            self.bids, self.bid_ms = {}, {}
            self._adopt(self.i, self.round + 1, owners, award, cost, ms)
            self.asked_at = now
        elif acked:
            self._adopt(self.i, self.round, owners, -1, 0.0)
        elif not (out != self.out_said or (missing or self.lagging)
                  and now - self.last_round >= self.resend_period):
            return []
        self.lagging = False
        self.last_round, self.out_said = now, out
        last = self.awards[-1] if self.awards and self.awards[-1].round == self.round else None
        if self.said[0] != self.round:
            self.said, self.round_wall = (self.round, set()), self.timer()
        self.said[1].add(digest(self.owners))
        return [Say("round", dict(round=self.round, owners=tuple(self.owners),
                                  award=last.task if last else -1,
                                  cost=last.cost if last else 0.0, ms=last.ms if last else 0.0,
                                  out=out))]

    def out(self) -> tuple[str, ...]:
        """Who the rounds leave out while their token lives: the stalled (RouteLogic.declared)
        and the silent (module docstring, "A robot that does not answer")."""
        why = dict(self.declared)
        why.update({self.problem.robots[k].id: "silent" for k in self.silent})
        return tuple(f"{r}:{w}" for r, w in sorted(why.items()))

    def _bid(self, now: float) -> list[Say]:
        """The answer to each Round heard from the auctioneer — a bid, or task −1 when nothing
        is open: either way its acknowledgement (the auctioneer repeats a Round until every
        robot answered it, so a lost Round or a lost bid costs one resend_period) — and the
        served tasks it has not yet shown DONE, every resend_period until it does."""
        if self.leading or self.round_from is None:
            return []
        target = self.auctioneer()
        if target != self.round_from:
            return []  # a new auctioneer: its first Round comes
        if not (self.answer_due or (self.unacked and now - self.last_bid >= self.resend_period)):
            return []
        self.answer_due, self.last_bid = False, now
        began = self.timer()
        task, cost = self.best_bid() if OPEN in self.owners else (-1, 0.0)
        ms = (self.timer() - began) * 1000.0
        name = self.problem.robots[target].id
        return [Say("bid", dict(auctioneer=name, round=self.round, task=task, cost=cost,
                                served=tuple(sorted(self.unacked)), ms=ms, seen=self.seen),
                    name)]
