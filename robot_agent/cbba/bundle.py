"""CBBA for one robot, as pure logic on an injected time (like MURDOCH's auction.Murdoch):
messages heard go in through `hear`, teammates coming and going through `teammate`, and
`tick(now)` runs one iteration — consensus already applied, release of outbid tasks, bundle
construction — and returns what to send. No bus, no clock, no threads.

The algorithm (Choi, Brunet & How 2009; docs/cbba.md):

* **State.** Per task j: the winning bid y_j and winner z_j as this robot believes them; per
  robot m: the time stamp s_m of the latest information from m; the *bundle* (tasks in the order
  they were added) and the *path* (the same tasks in the order they will be served).
* **Bundle construction** (§IV-A, Algorithm 3). While the bundle holds fewer than L_t tasks:
  for every known, unserved task j this robot can serve and does not hold, c_j = the largest
  increase of the path's score over every place j can go (`DiscountedRoute.insertion`; score
  Σ λ^start · reward), lowered to the least it was on any earlier stage of the bundle (below).
  Keep the tasks where c_j outbids y_j (c_j > y_j, or equal and this robot has the lower id),
  add the best (ties: lower task id) at the end of the bundle and at its best place in the path
  (ties: earliest place), and set y_j = c_j, z_j = this robot.
* **Consensus** (§IV-B, Table 1 in table.py) on every message heard, then the time stamps:
  s_k = when k's message was heard, s_m = max(s_m, k's s_m) for every other m.
* **Release** (eq. 11): if another robot now holds a task of the bundle, that task and every
  task added after it leave the bundle and the path, and those later ones are reset (y = 0,
  z = none) unless someone else holds them already: their scores counted on the lost task.

Departures from the paper, each for a reason given in docs/cbba.md:

* the marginal score is lowered to its least over the bundle's prefixes, so that it diminishes
  as the bundle grows (the paper's guarantees assume it does; this score does not always —
  where it does, the least is the paper's value);
* the *re-check*: after the release, a bundle that is no longer the greedy sequence of what the
  robot knows now is released from its first task the robot would not pick today (a task
  added while a better one looked taken); without it, CBBA can settle elsewhere than SGA;
* a robot that leaves the team (its token goes) has its wins reset and is treated as "none"
  wherever a message still names it; served tasks are final; a message older than the latest
  one heard from its sender is superseded; an optional communication range (`position` is
  where this robot is: its route's origin until the runtime tells it better);
* **what a message is believed for** (docs/security.md): a message whose winning bids are out
  of range (below 0, or above the task's reward: a marginal score is at most that) is refused
  whole; a task in its `done` counts as served only if its sender had won it as this robot
  knew it before the message — and no earlier than that winner could have served it (from
  its start, at its speed: `earliest`; a certified robot cannot end a task it won at once;
  a claim too early for its sender but not for another robot believed the winner, or for a
  robot the sender's own time stamps say it had news from since that robot could have served
  it, is taken as a relay of that robot's service and waits like one) —
  or once more than half of its teammates not known gone said so
  (a robot counted gone — a stall — never learns who won its tasks meanwhile, and every other
  robot relays their completion; a relay alone is not believed, or one liar's claim, relayed
  by those who believed it, would reach the majority). A claim believed on neither ground waits,
  counted once per task and sender as `done_unconfirmed` (not forged: an honest relay to a
  robot that missed who won looks the same, and so does the claim of a robot out of range that
  served a task it never heard it was outbid on); a waiting claim its sender's next message
  does not repeat was not its sender's (a robot's served tasks only grow) and is refused as
  forged (`done_not_won`: it said served what was not yet) once the task is served — by this
  robot, or believed on either ground —, the others are forgotten then. How long before that
  the claim came proves nothing: under a communication range this robot may learn of a
  service long after the robots near it (docs/security.md). A message stamped more than STAMP_SLACK
  after it was heard is refused (it would supersede its sender's real ones until then), and so
  is one whose time stamp of another robot is more than STAMP_SLACK after its own (news from
  the future: one such message, stamping every robot 10^12, froze every relay of theirs at its
  receivers for good — on a range-limited team a robot then kept tasks others had won, and both
  served them). The
  paper trusts every message: one robot saying every task done would otherwise end the
  mission with nothing served.
"""

from __future__ import annotations

import collections
import dataclasses
import math
import time
from typing import Iterable

from mrta_zenoh.planning import Problem, Task
from mrta_zenoh.planning.insertion import Origin, ranks, travel_times
from mrta_zenoh.refusal_tally import MALFORMED

from ..route.own_route import RouteLogic
from ..runtime.coordinator import Say
from .levels import Levels
from .messages import Bids
from .reading import Read, read
from .table import NONE, RESET, UPDATE, View, higher, resolve

# why a message, or a claim in it, was not believed (`Cbba.refused`)
BID_OUT_OF_RANGE = "bid_out_of_range"  # a winning bid below 0 or above the task's reward
NOT_WON = "done_not_won"               # a task said served before it was (module docstring)
UNCONFIRMED = "done_unconfirmed"       # a task said served by a robot not its known winner:
                                       # not believed alone, not forged until shown early
TOO_EARLY = "done_too_early"           # said served by its winner before it could have been
SUPERSEDED = "superseded"              # older than its sender's latest (late, or a replay)
STAMP_AHEAD = "stamp_ahead"            # stamped later than it was heard, by more than the slack
TASKS_AHEAD = "tasks_ahead"            # names tasks submitted that this robot has not taken yet
TASKS_LEEWAY = 100_000  # tasks a message may name beyond this robot's (the intake's bound)
STAMP_SLACK = 1.0  # s: a teammate's clock may run this far ahead of this robot's hearing it
CLAIM_SLACK = 3.0  # s: a completion may be said this long before its server could have made it
ROUNDING = 1e-9


class Cbba(RouteLogic):
    """One robot's CBBA. `problem` is the instance every robot reads; `discount` λ per second;
    `bundle_limit` L_t (None: unlimited); a task is known from `lookahead` seconds before its
    arrival (0: from its arrival; math.inf: all from the start); `diminishing`: bid the
    marginal score made diminishing, `recheck`: release a bundle that is no longer the greedy
    one (module docstring; False, False: the paper's rules); `comm_range`: messages from
    robots farther than this are not heard (None: every one); `resend_period`: the state is
    sent when it changes and at least this often (0: every tick, as in the paper's synchronous
    rounds); `origin`: where and when the robot's route begins."""

    listens = ("bids",)

    def __init__(self, problem: Problem, robot_id: str, *, discount: float = 0.95,
                 bundle_limit: int | None = None, lookahead: float = 0.0,
                 diminishing: bool = True, recheck: bool = True,
                 comm_range: float | None = None, resend_period: float = 1.0,
                 origin: Origin = Origin()):
        if not 0.0 < discount <= 1.0:
            raise ValueError(f"the discount λ must be in (0, 1], got {discount!r}")
        if bundle_limit is not None and bundle_limit < 1:
            raise ValueError(f"the bundle limit must be ≥ 1, got {bundle_limit!r}")
        self.problem = problem
        self.id = robot_id
        self.i = problem.robot_index(robot_id)
        self.index = {r.id: k for k, r in enumerate(problem.robots)}  # robot id → its index
        self.discount, self.bundle_limit, self.lookahead = discount, bundle_limit, lookahead
        self.diminishing, self.recheck, self.comm_range = diminishing, recheck, comm_range
        self.resend_period = resend_period
        self.rank = ranks([r.id for r in problem.robots])
        self.task_rank = ranks([t.id for t in problem.tasks])
        self.times = travel_times(problem, self.i)
        n_tasks = len(problem.tasks)
        self.y = [0.0] * n_tasks
        self.z = [NONE] * n_tasks
        self.stamps: dict[int, float] = {}
        self.bundle: list[int] = []
        self.path: list[int] = []
        self.done: set[int] = set()
        self.departed: set[int] = set()
        self.origin = origin
        self.position = (problem.robots[self.i].start if origin.task is None
                         else problem.tasks[origin.task].position)
        self.latest: dict[int, float] = {}  # sender → stamp of its latest message applied
        self.changed = True  # something to tell: the first tick always speaks
        self.last_sent = -math.inf
        self.out_said: tuple[str, ...] = ()  # who its last Bids said it counts out
        self._levels: Levels | None = None  # `_scores`
        self._still: tuple | None = None  # `_inputs` on which a tick's pass changed nothing
        self._least: tuple[tuple[Task, ...], float] | None = None  # `_least_reward`
        self.superseded = 0
        self.out_of_range = 0
        self._work = 0.0  # wall seconds spent on the bundle since the last Bids
        self.won: dict[int, set[int]] = {}  # task → every robot believed its winner so far
        # task → who said it served and was not believed (yet) → the stamp it first said so
        self.done_claims: dict[int, dict[int, float]] = {}
        self.too_early: set[tuple[int, int]] = set()  # (winner, task) said served too early
        # sender → {task: stamp} of its waiting claims its next message has still to repeat, and
        # (sender, task) of those a later message of that sender did not (`_check_claims`)
        self.unchecked: dict[int, dict[int, float]] = {}
        self.contradicted: set[tuple[int, int]] = set()
        self.refused: collections.Counter[tuple[str, str, str, bool]] = collections.Counter()
        self.base_reward: dict[int, Task] = {}  # a task as it came, before its priority weighed it

    # ------------------------------------------------------------------ tasks at run time
    def tasks_added(self, growth, now: float) -> None:
        """Tasks submitted at run time (runtime/growth.py): the problem grows by them (every
        robot's the same way, at the same tick) — a new column of the winning-bid table,
        unassigned — and each is a candidate from then on (its arrival is the instant it
        entered). Priority weighs its reward (`weighted`)."""
        before = len(self.problem.tasks)
        grown = growth.problem(self.problem)
        priority = {t.id: t.priority for t in growth.tasks}
        for j in range(before, len(grown.tasks)):
            self.base_reward[j] = grown.tasks[j]
        self.problem = dataclasses.replace(grown, tasks=grown.tasks[:before] + tuple(
            weighted(t, priority.get(t.id, 0)) for t in grown.tasks[before:]))
        self._grown()

    def task_priority(self, task_id: str, priority: int, now: float) -> None:
        """A new priority weighs the task's reward from now on (`weighted`, from its base)."""
        try:
            j = self.problem.task_index(task_id)
        except KeyError:
            return
        tasks = list(self.problem.tasks)
        tasks[j] = weighted(self.base_reward.setdefault(j, tasks[j]), priority)
        self.problem = dataclasses.replace(self.problem, tasks=tuple(tasks))
        self._grown()

    def _grown(self) -> None:
        n = len(self.problem.tasks)
        self.y += [0.0] * (n - len(self.y))
        self.z += [NONE] * (n - len(self.z))
        self.task_rank = ranks([t.id for t in self.problem.tasks])
        self.times = travel_times(self.problem, self.i)
        self._levels = None
        self.changed = True

    # ------------------------------------------------------------------ what it tells the runtime
    @property
    def active_task(self) -> str | None:
        """The first task of the path: the one to work on now."""
        return self.problem.tasks[self.path[0]].id if self.path else None

    def winners(self) -> dict[str, str]:
        """Task id → winner id, as this robot believes it (served tasks excluded)."""
        p = self.problem
        return {p.tasks[j].id: p.robots[w].id for j, w in enumerate(self.z)
                if w != NONE and j not in self.done}

    def route(self) -> list[str]:
        return [self.problem.tasks[j].id for j in self.path]

    # ------------------------------------------------------------------ what was heard
    def teammate(self, robot: str, alive: bool) -> None:
        """A robot joined or left the team (its agent token). The paper's team is fixed; one that
        leaves can no longer serve what it won, so its wins are reset here, and every message
        that still names it as a winner reads as "none" (`_view`): relayed old news cannot bring
        its wins back."""
        k = self.index.get(robot)
        if k is None or k == self.i:
            return
        if alive:
            self.departed.discard(k)
            return
        self.departed.add(k)
        for j, w in enumerate(self.z):
            if w == k and j not in self.done:
                self._set(j, NONE, 0.0)

    def hear(self, kind: str, sender: str, msg: Bids, at: float) -> bool:
        """Apply a teammate's Bids (Table 1 per task, then the time stamps); False when it is
        malformed (an index outside the instance) and was dropped whole."""
        k = self.index.get(sender)
        if k is None:
            return False
        if kind != "bids" or not isinstance(msg, Bids) or k == self.i:
            return False
        said = read(msg)  # once per message, whoever hears it (reading.py)
        named = said.named
        if not self._valid(named, TASKS_LEEWAY):
            self.refused[("bids", sender, MALFORMED, True)] += 1
            return False
        if not self._valid(named):  # tasks this robot has not taken yet: not now (it resends)
            self.refused[("bids", sender, TASKS_AHEAD, False)] += 1
            return True
        if k in self.departed:
            return True
        if (self.comm_range is not None
                and math.dist(self.position, (msg.x, msg.y)) > self.comm_range):
            self.out_of_range += 1
            return True
        if msg.header.stamp > at + STAMP_SLACK or \
                max(said.stamps.values(), default=-math.inf) > msg.header.stamp + STAMP_SLACK:
            self.refused[("bids", sender, STAMP_AHEAD, True)] += 1
            return True  # it would supersede its sender's real messages until then, or (its
            # news of another robot later than itself) every relay of that robot's for good
        if msg.header.stamp < self.latest.get(k, -math.inf):
            self.superseded += 1  # delivered out of order: a later one was applied already
            self.refused[("bids", sender, SUPERSEDED, False)] += 1
            return True
        if not self._bids_in_range(msg, said):
            self.refused[("bids", sender, BID_OUT_OF_RANGE, True)] += 1
            return True  # refused whole, and counted here
        self.latest[k] = msg.header.stamp
        stamp = msg.header.stamp
        if self.unchecked.get(k):
            self._check_claims(k, stamp, msg.done)
        for j in msg.done:
            if j in self.done:
                continue
            if k in self.won.get(j, ()):
                if stamp >= self.earliest(k, j) - CLAIM_SLACK:
                    self._mark_done(j)
                    continue
                if not self._relay_possible(k, j, stamp, said.stamps):
                    if (k, j) not in self.too_early:  # counted once; believed once it could be
                        self.too_early.add((k, j))
                        self.refused[("bids", sender, TOO_EARLY, True)] += 1
                    continue
                # too early for k, not for another robot believed its winner: k may relay that
                # robot's service (k won it once, lost it, heard it served) — a claim that waits
            claims = self.done_claims.setdefault(j, {})
            if k not in claims:
                self.refused[("bids", sender, UNCONFIRMED, False)] += 1
                claims[k] = stamp
                self.unchecked.setdefault(k, {})[j] = stamp
            if len(set(claims) - self.departed) > self._others() / 2:
                self._mark_done(j)
        s_k, theirs = said.stamps, said.winners
        z, y, done, departed = self.z, self.y, self.done, self.departed
        # Table 1 leaves a task alone where both sides name the same winner and bid (rows 2,
        # 5, 11, 17 keep or re-take that very view), and no task's action depends on another's,
        # so only the tasks where the views differ are resolved: 100 robots hear ≈ 10⁴
        # messages a round, each naming a winner for most of the 100 tasks
        for j, (w, bid) in theirs.items():
            if w in departed:
                w, bid = NONE, 0.0  # a winner that left the team reads as none
            if (w != z[j] or bid != y[j]) and j not in done:
                self._resolve(j, k, View(w, bid), s_k)
        for j, w in enumerate(z):
            if w != NONE and j not in theirs and j not in done:
                self._resolve(j, k, View(NONE, 0.0), s_k)
        self.stamps[k] = max(self.stamps.get(k, -math.inf), at)
        for m, t in s_k.items():
            if m != self.i and t > self.stamps.get(m, -math.inf):
                self.stamps[m] = t
        return True

    def served(self, task_id: str, at: float) -> None:
        """This robot finished serving `task_id` at `at`: it leaves bundle and path for good, and
        the route now begins there and then."""
        j = self.problem.task_index(task_id)
        if j in self.bundle:
            self.bundle.remove(j)
        if j in self.path:
            self.path.remove(j)
        self.z[j] = self.i
        self.done.add(j)
        self._settle(j)
        self.relocate(Origin(j, at))
        self.position = self.problem.tasks[j].position

    def relocate(self, origin: Origin) -> None:
        """The robot's route now begins at `origin` — say an idle robot whose plan still starts
        in the past, or one held up on its way: every score is counted from there (bids already
        in the bundle stand until the re-check finds the bundle no longer greedy)."""
        self.origin = origin
        self._levels = None
        self.changed = True

    # ------------------------------------------------------------------ one iteration
    def tick(self, now: float) -> list[Say]:
        started = time.perf_counter()  # wall time: a computation's cost is the machine's
        candidates = self._candidates(now)
        before = self._inputs(candidates)
        if before != self._still:
            self._release()
            if self.recheck:
                self._recheck(candidates)
            self._build(candidates)
            # a pass that changed nothing changes nothing on the same inputs again: the next
            # ticks skip it until something it reads changes (most ticks of a settled team)
            self._still = before if self._inputs(candidates) == before else None
        self._work += time.perf_counter() - started
        out = self.out()
        if not self.changed and out == self.out_said and now - self.last_sent < self.resend_period:
            return []
        # a decision: the table changed since the last Bids (a resend of it is none)
        ms = round(self._work * 1000.0, 3) if self.changed else 0.0
        self._work = 0.0
        self.changed, self.last_sent, self.out_said = False, now, out
        self.stamps[self.i] = now
        winners = tuple((j, w, self.y[j]) for j, w in enumerate(self.z)
                        if w != NONE and j not in self.done)
        stamps = tuple(sorted((m, t) for m, t in self.stamps.items() if m not in self.departed))
        x, y = self.position
        return [Say("bids", dict(winners=winners, stamps=stamps, done=tuple(sorted(self.done)),
                                 x=x, y=y, ms=ms, out=out))]

    def _inputs(self, candidates: list[int]) -> tuple:
        """Everything release, re-check and build read (the levels stand for the problem, the
        origin and the scores, and are replaced when any of those changes)."""
        return (self._levels, tuple(self.z), tuple(self.y), tuple(self.bundle),
                tuple(self.path), tuple(candidates))

    def _candidates(self, now: float) -> list[int]:
        """The tasks this robot may bid on: known by now, unserved, within its capabilities."""
        known = now + self.lookahead
        p = self.problem
        return [j for j, task in enumerate(p.tasks)
                if j not in self.done and task.arrival <= known and p.capable(self.i, j)]

    def _release(self) -> None:
        """Eq. 11: the first bundle task someone else now holds goes, with every later one."""
        lost = next((n for n, j in enumerate(self.bundle) if self.z[j] != self.i), None)
        if lost is not None:
            self._release_from(lost)

    def _release_from(self, n: int) -> None:
        """The bundle's n-th task (from 0) and every later one leave the bundle and the path;
        those this robot still holds are reset (the later ones' scores counted on the lost one;
        the n-th one itself when the re-check, not an outbid, released it)."""
        for j in self.bundle[n:]:
            if self.z[j] == self.i and j not in self.done:
                self._set(j, NONE, 0.0)
        gone = set(self.bundle[n:])
        del self.bundle[n:]
        self.path = [j for j in self.path if j not in gone]
        if self._levels is not None:
            self._levels.cut(n)  # the shorter bundle's levels stay what they were

    def _pick(self, levels: Levels, k: int, candidates: Iterable[int],
              own: int | None = None) -> tuple[float, int, int] | None:
        """The greedy choice on level k: the candidate whose score outbids what this robot
        knows of it (a task it holds itself, `own` or later in its bundle, counts as free), the
        largest score first, then the lower task id: (score, task, place)."""
        held = set(self.bundle[:k])
        z, y, i, rank = self.z, self.y, self.i, self.rank

        def outbids(j: int, score: float) -> bool:
            return j == own or z[j] == i or higher(View(i, score), View(z[j], y[j]), rank)
        return levels.best(k, [j for j in candidates if levels.known(j) and j not in held],
                           outbids, self.task_rank)

    def _recheck(self, candidates: list[int]) -> None:
        """The bundle must be the greedy sequence of what this robot knows now: from the first
        task it would no longer pick at its place (another task became free meanwhile, and
        scores more), the bundle goes as if outbid. The paper's proof that CBBA ends as SGA
        does relies on this; its bundle construction alone keeps a task added while a better
        one seemed taken (docs/cbba.md, "The re-check")."""
        levels = self._scores(candidates)
        for k, held in enumerate(self.bundle):
            best = self._pick(levels, k, candidates, own=held)
            if best is None or best[1] != held:
                self._release_from(k)
                return

    def _build(self, candidates: list[int]) -> None:
        """Algorithm 3: add the greedy choice at the end of the bundle and at its place in the
        path until none is left or the bundle holds L_t tasks."""
        levels = self._scores(candidates)
        while self.bundle_limit is None or len(self.bundle) < self.bundle_limit:
            best = self._pick(levels, len(self.bundle),
                              [j for j in candidates if self.z[j] != self.i])
            if best is None:
                return
            score, j, where = best
            self.bundle.append(j)
            self.path.insert(where, j)
            self._set(j, self.i, score)
            levels.grown()

    def _scores(self, candidates: list[int]) -> Levels:
        """The bundle's `Levels`, kept while bundle, path and origin change only by
        `_release_from` and `_build`, told of candidates it lacks."""
        if self._levels is None:
            self._levels = Levels(self.problem, self.i, self.discount, self.origin, self.times,
                                  self.diminishing, lambda: (self.bundle, self.path))
        self._levels.know(candidates)
        return self._levels

    # ------------------------------------------------------------------ helpers
    def _resolve(self, j: int, k: int, sender_view: View, s_k: dict[int, float]) -> None:
        """Table 1 on task j for sender k's view of it, carried out."""
        action = resolve(self.i, k, sender_view, View(self.z[j], self.y[j]), s_k, self.stamps,
                         self.rank).action
        if action == UPDATE:
            self._set(j, sender_view.winner, sender_view.bid)
        elif action == RESET:
            self._set(j, NONE, 0.0)

    def _bids_in_range(self, msg: Bids, said: Read) -> bool:
        """Whether every winning bid is in [0, its task's reward] (give or take the rounding):
        all bids within the least reward need no look at each task."""
        if said.highest is None:
            return True
        if -ROUNDING <= said.lowest and said.highest <= self._least_reward() + ROUNDING:
            return True  # NaN fails both: looked at below
        tasks = self.problem.tasks
        return all(-ROUNDING <= y <= tasks[j].reward + ROUNDING for j, _, y in msg.winners)

    def _least_reward(self) -> float:
        tasks = self.problem.tasks
        if self._least is None or self._least[0] is not tasks:
            self._least = (tasks, min((t.reward for t in tasks), default=0.0))
        return self._least[1]

    def _set(self, j: int, winner: int, bid: float) -> None:
        if (self.z[j], self.y[j]) != (winner, bid):
            self.z[j], self.y[j] = winner, bid
            self.changed = True
            if winner != NONE:
                self.won.setdefault(j, set()).add(winner)

    def _others(self) -> int:
        """The teammates not known to have left (what a majority is counted over)."""
        return len(self.problem.robots) - 1 - len(self.departed)

    def _view(self, view: View) -> View:
        """A winner that left the team reads as none."""
        return View(NONE, 0.0) if view.winner in self.departed else view

    def _relay_possible(self, k: int, j: int, stamp: float, s_k: dict[int, float]) -> bool:
        """Whether k's `done` of j, too early for k, may relay another robot's service: another
        robot believed j's winner could have served it by `stamp` (seen after a partition: k won
        j, lost it to a teammate on its side, and reports that teammate's service when it
        rejoins), or k's own time stamps `s_k` say it had news from a robot able to serve j
        from when that robot could have served it (under a communication range, the study's
        file 07: this robot never heard that robot win j — nothing told it across the gap — yet
        the news of its service came to k the way every news of it does, with its time stamp,
        s_km ≥ when m said it). Then it waits for a majority like any relay instead of being
        refused as forged."""
        if any(w != k and stamp >= self.earliest(w, j) - CLAIM_SLACK for w in self.won[j]):
            return True
        return any(m != k and m != self.i and self.problem.capable(m, j)
                   and t >= self.earliest(m, j) - CLAIM_SLACK for m, t in s_k.items())

    def earliest(self, k: int, j: int) -> float:
        """The earliest robot k could have finished task j: from its start at its speed (the
        instance's; a shortest path, so no route through other tasks is faster), not before the
        task arrived, plus its service."""
        task = self.problem.tasks[j]
        return max(self.problem.travel(k, None, j), task.arrival) + task.service

    def _mark_done(self, j: int) -> None:
        """Another robot served j (believed on the message just heard): served tasks are final. If this robot still held it (two robots served one task before
        agreeing), it goes like an outbid one, with every task added after it."""
        if j in self.done:
            return
        self.done.add(j)
        self._settle(j)
        self.changed = True
        if j in self.bundle:
            self._release_from(self.bundle.index(j))

    def _settle(self, j: int) -> None:
        """j is served: each claim of it that waited (`done_claims`) is no
        longer unconfirmed; one its sender contradicted since is refused as forged, the others
        are forgotten — or judged at their sender's next message (`_check_claims`).

        Not by how long before `at` it came (the rule until the study's file 07): `at` is only
        when this robot learned of the service, which under a communication range can be long
        after it — an honest robot relays it, or served the task itself believing it won it (a
        robot out of range never heard it was outbid), long before its news reaches here."""
        for m in self.done_claims.pop(j, {}):
            sender = self.problem.robots[m].id
            unconfirmed = ("bids", sender, UNCONFIRMED, False)
            self.refused[unconfirmed] -= 1
            if self.refused[unconfirmed] <= 0:
                del self.refused[unconfirmed]
            if (m, j) in self.contradicted:
                self.contradicted.discard((m, j))
                self.refused[("bids", sender, NOT_WON, True)] += 1

    def _check_claims(self, k: int, stamp: float, done: tuple[int, ...]) -> None:
        """k's message stamped `stamp` against k's earlier waiting claims: a robot's served
        tasks only grow (served tasks are final, and every Bids lists them all), so a later
        message of k's without a task it said served shows that claim was not k's — a forger
        under k's key said served what was not yet (`done_not_won`), refused at once if the
        task is served by now, else once it is (`_settle`). A claim k repeats is consistent and
        left to the majority; the one check each claim needs is k's next message."""
        mine = self.unchecked[k]
        said = set(done)
        for j, t in list(mine.items()):
            if stamp <= t:
                continue
            del mine[j]
            if j in said:
                continue
            if j in self.done:
                self.refused[("bids", self.problem.robots[k].id, NOT_WON, True)] += 1
            else:
                self.contradicted.add((k, j))

    def _valid(self, named: tuple[int, int, int], leeway: int = 0) -> bool:
        least, task, robot = named
        return (least >= 0 and task < len(self.problem.tasks) + leeway
                and robot < len(self.problem.robots))


def weighted(task: Task, priority: int) -> Task:
    """A task's reward weighed by its priority (tasks submitted at run time, issue 50): reward ·
    (1 + priority) for a priority above 0 — a robot's marginal score for it, Σ λ^start · reward,
    grows with it, so it outbids the instance's tasks (all priority 0) near it and is served
    earlier in a path. Not in the paper, whose tasks carry a reward and no priority; a reward
    is how CBBA's score says "worth more" (docs/tasks.md)."""
    return dataclasses.replace(task, reward=task.reward * (1 + max(priority, 0)))
