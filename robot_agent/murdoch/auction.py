"""MURDOCH's decisions for one robot, as pure logic on an injected time (like ALLIANCE's
HighLevel): messages heard go in through `hear`, teammates and their subjects through `teammate`
and `teammate_subject`, and `tick(now, readings)` returns what to publish (the runtime's `Say`).
No bus, no clock, no threads — the agent wires it, tests drive it in virtual time.

The protocol (Gerkey & Matarić 2002; docs/murdoch.md):

* **Auction.** An auctioneer publishes an Announcement (task, required resources, bid window).
  Every *idle* robot whose required resources are fresh and whose progress evaluator says the
  task is applicable bids its utility: `skill_weight·level − distance_weight·distance` to the
  nearest of the task's locations (if it has any and the robot knows its pose). When the window
  closes the auctioneer awards greedily over every auction it closes at that tick — highest
  utility first, ties to the lower robot id, each robot and task at most once — a single-round,
  first-price auction. No bids, no award. A robot awarded a task (by this auctioneer or
  another) is busy from the award until its claim or release is heard, or for a lease: its
  claim takes a tick and a delivery to arrive, and an auction closing meanwhile must not
  award it a second task, which it would only release.
* **Leases.** The winner publishes a Claim at once and every renewal_period. A task none of
  whose claims was heard for lease_timeout is unheld again and is auctioned anew. A winner
  whose progress evaluator (or resources) stays false for give_up_delay releases the task and
  does not bid for it again for as long; a winner whose layers say the task is done
  (Layer.done) releases it at once. A robot awarded a task while busy releases it at once.
* **Who auctions.** Every robot knows the mission's tasks, and any robot may auction an unheld
  one it serves (its subjects: the tasks it has a skill for; it hears only their announcements,
  and must hear whether someone else announced). Each robot advertises its subjects (a
  liveliness token each, `teammate_subject`), so a task's auctioneers are ranked among the live
  robots that serve it: the one of rank k (k-th lowest id among them, this one included)
  announces once the task has been unheld for k·reannounce_period and nobody announced it for
  (k+1)·reannounce_period. The lowest-id robot that serves a task therefore announces it at once
  and re-announces every period while nobody bids; the others stay silent while it lives and
  step in, in turn, when it dies or is cut off. Gerkey's MURDOCH let the task's introducer be
  its auctioneer; in a team with no introducer this rule is what keeps allocation going when
  any robot is lost.
* **Progress monitoring** (Gerkey & Matarić's auctioneer watching its contracts). A lease
  says the holder is alive, not that the task advances: a robot that keeps renewing but makes
  no progress (a stall) would hold its task for ever. So the task's auctioneer — ranked as for
  announcements, among the live robots that serve it other than the holder — revokes a
  contract it has heard claimed for longer than the task's progress_timeout (the task not done:
  a holder whose progress evaluator says it is done releases it), rank k after k more
  reannounce_periods unless a revocation came first. Every robot then ignores that contract's
  claims and counts the task unheld (so it is auctioned again), bars the holder from it for a
  progress_timeout, and the holder gives it back.
* **Two holders** (two auctioneers on either side of a healed partition): the earlier
  (since, id) keeps the task, the other releases it. Both compare the same reported numbers.
* **What a Revoke is believed for** (issue 51: a message believed only for what its sender can
  claim). A monitor revokes only a contract that has run its progress_timeout, so a revocation
  of a contract this robot heard claimed (or holds) is believed only once that contract has run
  its progress_timeout as this robot saw it, less a lease for delivery delays; an earlier one is
  refused and counted (`revoke_early`): a forger — or a certified robot under its own key —
  cannot end a contract that is within its time. A revocation of a contract this robot never
  heard of (`revoke_unknown`: it would bar its "holder" from the task for a progress_timeout)
  or from a robot that does not serve the task (`not_monitor`: only a server monitors) is
  refused too — counted, not called forged: a robot cut off from the claims, or one whose
  view of the servers lags, refuses an honest one the same way. What is left is what a monitor
  says anyway: a revocation of an overdue contract, at most a lease before the real monitor.
* **What a Claim is believed for.** A claim starts a contract; one whose `since` is earlier
  than the holder's makes the holder yield (two holders after a partition). A holder yields
  only to a contract it has heard *renewed* (a second claim at least half a renewal period
  after the first, as every holder renews), and a contract heard once counts for one lease of
  this robot's at most: a single forged claim, however early its `since`, displaces nobody and
  keeps a task or a robot "held" for at most `lease_timeout`; one that lapses unrenewed where
  it would have displaced this robot is counted (`claim_not_renewed`, not called forged: a
  holder stopped right after its first claim looks the same). A claim from a robot that this
  robot heard renew another contract after that claim's `since` (plus a lease) is refused and
  counted as forged (`claim_contradicted`): a robot holds one task at a time.
* **What an Award is believed for.** A robot takes a task awarded to it only in an auction it
  bid in (that auctioneer, that auction number, that task, within the bid window and a lease of
  its bid); another is refused and counted (`award_not_bid`), and the robot says so at once
  with a Release of the task, so that its teammates stop counting it busy and the task held:
  a forged Award cannot make a robot take a task, and holds the task for a delivery, not a
  lease. A robot that serves the task (and so hears its announcements) believes an Award only
  for an auction its sender announced for that task within the bid window and a lease
  (`award_not_announced`; counted, not called forged: a robot that joined after the
  announcement refuses an honest one the same way).
"""

from __future__ import annotations

import collections
import math
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.messages import Message

from ..runtime.coordinator import Say
from .messages import Announcement, Award, Bid, Claim, Release, Revoke
from .params import MurdochRobot, MurdochTask

REVOKE_EARLY = "revoke_early"  # a contract revoked before its progress_timeout had run
REVOKE_UNKNOWN = "revoke_unknown"  # a contract this robot never heard claimed (nor held)
NOT_MONITOR = "not_monitor"  # revoked by a robot that does not serve the task
AWARD_NOT_BID = "award_not_bid"  # this robot awarded a task in an auction it did not bid in
AWARD_NOT_ANNOUNCED = "award_not_announced"  # an award for an auction its sender never announced
CLAIM_CONTRADICTED = "claim_contradicted"  # its sender renewed another contract since
CLAIM_NOT_RENEWED = "claim_not_renewed"  # an earlier contract heard once, never renewed

class Readings(Protocol):
    """What the robot knows of itself (from its sensor and evaluator plugins)."""

    def fresh(self, topic: str, now: float) -> bool: ...
    def applicable(self, task_id: str, now: float) -> bool: ...
    def done(self, task_id: str, now: float) -> bool: ...
    def pose(self) -> tuple[float, float] | None: ...


class Change(NamedTuple):
    """A change of this robot's task, for the log and the tests: won / released."""

    kind: str
    task_id: str
    reason: str


@dataclass
class Lease:
    since: float
    heard: float
    lease: float
    renewed: bool = False  # heard again, half a renewal period or more after its first claim

    def expiry(self) -> float:
        return self.heard + self.lease


@dataclass
class OpenAuction:
    number: int
    task_id: str
    deadline: float
    bids: dict[str, float] = field(default_factory=dict)


class Murdoch:
    def __init__(self, robot_id: str, robot: MurdochRobot, tasks: dict[str, MurdochTask]):
        self.id = robot_id
        self.p = robot
        self.tasks = tasks
        self.teammates: set[str] = set()
        self.servers: dict[str, set[str]] = {t: set() for t in tasks}  # task → who advertise it
        self.leases: dict[str, dict[str, Lease]] = {t: {} for t in tasks}
        self.held_until: dict[str, float] = {}     # task → when its last claim/award lapses
        self.awarded: dict[str, tuple[str, float]] = {}  # winner → (task, until): not yet claimed
        self.last_announced: dict[str, float] = {}
        self.open: dict[int, OpenAuction] = {}
        self.next_auction = 1
        self._announcements: list[tuple[str, Announcement, float]] = []
        self._awards: list[tuple[str, Award, float]] = []
        # (auctioneer, auction) → (task, until): the bids this robot sent, while an award for
        # them may still come (module docstring: an Award is believed only for a bid)
        self.bids_sent: dict[tuple[str, int], tuple[str, float]] = {}
        # (auctioneer, auction) → (task, until): announcements heard, while an award may come
        self.announced: dict[tuple[str, int], tuple[str, float]] = {}
        self._refutations: list[str] = []  # tasks awarded to this robot that it never bid for
        self.held_since: dict[str, float] = {}  # task → since of this robot's last contract
        self.task: str | None = None
        self.since = 0.0
        self.last_claim: float | None = None
        self.stalled_since: float | None = None
        self.cooldown: dict[str, float] = {}
        self.start: float | None = None
        # progress monitoring: task → holder → (since, first heard) of the contract it claims;
        # task → holder → (since, barred until) of the last contract revoked
        self.contracts: dict[str, dict[str, tuple[float, float]]] = {t: {} for t in tasks}
        self.revoked: dict[str, dict[str, tuple[float, float]]] = {t: {} for t in tasks}
        self._revocations: list[tuple[str, Revoke]] = []  # of this robot's own contract
        # (kind, sender, reason, forged) → messages not believed (module docstring)
        self.refused: collections.Counter[tuple[str, str, str, bool]] = collections.Counter()

    # ------------------------------------------------------------------ what was heard
    def teammate(self, robot: str, alive: bool) -> None:
        (self.teammates.add if alive else self.teammates.discard)(robot)

    def teammate_subject(self, robot: str, task_id: str, alive: bool) -> None:
        """A teammate advertises (or stopped advertising) that it serves `task_id`; tasks not
        in the tasks file are none of this robot's business."""
        servers = self.servers.get(task_id)
        if servers is not None:
            (servers.add if alive else servers.discard)(robot)

    @property
    def subjects(self) -> tuple[str, ...]:
        """The tasks this robot serves (a skill with level > 0): the announcement subjects it
        hears, bids on and auctions. Static: resources stay a check at bid time."""
        return tuple(t for t in self.tasks if (s := self.p.skill(t)) is not None and s.level > 0)

    def hear(self, kind: str, sender: str, msg: Message, t: float) -> bool:
        """One message heard at `t` (this robot's own announcements too: they say it announced);
        False when `kind` is none of MURDOCH's or `msg` not of its type."""
        match kind, msg:
            case "announcement", Announcement():
                self._on_announcement(sender, msg, t)
            case "bid", Bid():
                self._on_bid(sender, msg, t)
            case "award", Award():
                self._on_award(sender, msg, t)
            case "claim", Claim():
                self._on_claim(sender, msg, t)
            case "release", Release():
                self._on_release(sender, msg, t)
            case "revoke", Revoke():
                self._on_revoke(sender, msg, t)
            case _:
                return False
        return True

    def _on_announcement(self, sender: str, msg: Announcement, t: float) -> None:
        if msg.task_id not in self.subjects:  # heard only on its subjects: a mislabelled one
            return
        self.last_announced[msg.task_id] = max(self.last_announced.get(msg.task_id, t), t)
        if sender != self.id:
            self._announcements.append((sender, msg, t))
            self.announced[(sender, msg.auction)] = (msg.task_id,
                                                     t + msg.bid_window + self.p.lease_timeout)

    def _on_bid(self, sender: str, msg: Bid, t: float) -> None:
        auction = self.open.get(msg.auction)
        if msg.auctioneer != self.id or auction is None or auction.task_id != msg.task_id:
            return
        if t > auction.deadline + EPSILON:
            return
        auction.bids[sender] = msg.utility

    def _on_award(self, sender: str, msg: Award, t: float) -> None:
        if msg.task_id not in self.tasks:
            return
        if msg.winner == self.id and \
                self.bids_sent.get((sender, msg.auction), (None,))[0] != msg.task_id:
            self.refused[("award", sender, AWARD_NOT_BID, True)] += 1
            if msg.task_id != self.task:
                self._refutations.append(msg.task_id)
            return
        if msg.task_id in self.subjects and sender != self.id and \
                self.announced.get((sender, msg.auction), (None,))[0] != msg.task_id:
            self.refused[("award", sender, AWARD_NOT_ANNOUNCED, False)] += 1
            return
        # the winner claims at its next tick: until then (and for a lease) the task is taken
        self.held_until[msg.task_id] = max(self.held_until.get(msg.task_id, t),
                                           t + self.p.lease_timeout)
        if msg.winner != self.id:
            self.awarded[msg.winner] = (msg.task_id, t + self.p.lease_timeout)
        else:
            self._awards.append((sender, msg, t))

    def _on_claim(self, sender: str, msg: Claim, t: float) -> None:
        if msg.task_id not in self.tasks or sender == self.id:
            return
        if self.revoked[msg.task_id].get(sender, (None,))[0] == msg.since:
            return  # a contract its auctioneer ended: the claim says nothing any more
        if any(task != msg.task_id and lease.heard > msg.since + self.p.lease_timeout + EPSILON
               for task, leases in self.leases.items() if (lease := leases.get(sender))):
            self.refused[("claim", sender, CLAIM_CONTRADICTED, True)] += 1
            return
        contract = self.contracts[msg.task_id].get(sender)
        if contract is None or contract[0] != msg.since:
            contract = self.contracts[msg.task_id][sender] = (msg.since, t)
        renewed = t - contract[1] >= self.p.renewal_period / 2 - EPSILON
        cap = 10 * self.p.lease_timeout if renewed else self.p.lease_timeout
        lease = Lease(msg.since, t, min(msg.lease, cap), renewed)
        self.leases[msg.task_id][sender] = lease
        self.awarded.pop(sender, None)  # its lease says it is busy from now on
        self.held_until[msg.task_id] = max(self.held_until.get(msg.task_id, t), lease.expiry())

    def _on_release(self, sender: str, msg: Release, t: float) -> None:
        if msg.task_id not in self.tasks:
            return
        self.leases[msg.task_id].pop(sender, None)
        if self.awarded.get(sender, (None,))[0] == msg.task_id:
            del self.awarded[sender]  # it turned the award down (or gave the task back)
        others = [lease.expiry() for lease in self.leases[msg.task_id].values()
                  if lease.expiry() >= t]
        others += [until for task, until in self.awarded.values() if task == msg.task_id]
        self.held_until[msg.task_id] = max(others, default=t)

    def _on_revoke(self, sender: str, msg: Revoke, t: float) -> None:
        if msg.task_id not in self.tasks:
            return
        if msg.holder != self.id and \
                self.revoked[msg.task_id].get(msg.holder, (None,))[0] == msg.since:
            return  # already ended (another monitor, or this robot's own, said it first)
        reason = self._unbelieved(sender, msg, t)
        if reason is not None:
            self.refused[("revoke", sender, reason, reason == REVOKE_EARLY)] += 1
            return
        if msg.holder == self.id:
            self._revocations.append((sender, msg))
        else:
            self._end_contract(msg.task_id, msg.holder, msg.since, t)

    def _unbelieved(self, sender: str, msg: Revoke, t: float) -> str | None:
        """Why `msg` is not believed (module docstring), or None: its sender serves no such
        task, it revokes a contract this robot never knew (its own, or one it heard claimed),
        or one that has not run its progress_timeout, less a lease."""
        if sender not in self.servers[msg.task_id]:
            return NOT_MONITOR
        if msg.holder == self.id:
            if msg.since not in ((self.since if self.task == msg.task_id else None),
                                 self.held_since.get(msg.task_id)):
                return REVOKE_UNKNOWN
            first = msg.since
        else:
            contract = self.contracts[msg.task_id].get(msg.holder)
            if contract is None or contract[0] != msg.since:
                return REVOKE_UNKNOWN
            first = contract[1]
        timeout = self.tasks[msg.task_id].progress_timeout
        return REVOKE_EARLY if t < first + timeout - self.p.lease_timeout - EPSILON else None

    def _end_contract(self, task: str, holder: str, since: float, t: float) -> None:
        """`holder`'s contract for `task` (claimed `since`) is over: its claims are ignored,
        it may not win the task for a progress_timeout, and the task is unheld unless someone
        else holds it."""
        self.revoked[task][holder] = (since, t + self.tasks[task].progress_timeout)
        if self.contracts[task].get(holder, (None,))[0] == since:
            del self.contracts[task][holder]
        lease = self.leases[task].get(holder)
        if lease is not None and lease.since == since:
            del self.leases[task][holder]
        if self.awarded.get(holder, (None,))[0] == task:
            del self.awarded[holder]
        self.held_until[task] = max((x.expiry() for x in self.leases[task].values()
                                     if x.expiry() >= t), default=t)

    def barred(self, task: str, robot: str, now: float) -> bool:
        """Whether `robot` may not win `task` now: its contract for it was revoked lately."""
        return self.revoked[task].get(robot, (0.0, -math.inf))[1] > now

    # ------------------------------------------------------------------ one tick
    def tick(self, now: float, readings: Readings) -> tuple[list[Say], list[Change]]:
        if self.start is None:
            self.start = now
        out: list[Say] = []
        changes: list[Change] = []
        self._expire(now)
        for task in self._refutations:  # awards it never bid for (module docstring)
            out.append(Say("release", dict(task_id=task, reason=f"{AWARD_NOT_BID}: no bid")))
        self._refutations = []
        self._take_awards(now, out, changes)
        self._take_revocations(now, out, changes)
        self._keep_or_release(now, readings, out, changes)
        self._monitor(now, out)
        self._bid(now, readings, out)
        self._close_auctions(now, readings, out, changes)
        self._announce(now, readings, out)
        return out, changes

    def _expire(self, now: float) -> None:
        for heard in (self.bids_sent, self.announced):
            for auction in [a for a, (_, until) in heard.items() if until < now]:
                del heard[auction]
        for robot in [r for r, (_, until) in self.awarded.items() if until < now]:
            del self.awarded[robot]
        for task, leases in self.leases.items():
            for robot in [r for r, lease in leases.items() if lease.expiry() < now]:
                lease = leases.pop(robot)
                if not lease.renewed and task == self.task and \
                        (lease.since, robot) < (self.since, self.id):
                    self.refused[("claim", robot, CLAIM_NOT_RENEWED, False)] += 1

    def capable(self, task_id: str, now: float, readings: Readings) -> bool:
        skill = self.p.skill(task_id)
        return (skill is not None and skill.level > 0 and now >= self.cooldown.get(task_id, -math.inf)
                and self.progressing(task_id, now, readings))

    def progressing(self, task_id: str, now: float, readings: Readings) -> bool:
        return (all(readings.fresh(r, now) for r in self.tasks[task_id].resources)
                and readings.applicable(task_id, now))

    def utility(self, task_id: str, readings: Readings) -> float:
        skill = self.p.skill(task_id)
        value = self.p.skill_weight * (skill.level if skill else 0.0)
        pose, places = readings.pose(), self.tasks[task_id].locations
        if pose is not None and places and self.p.distance_weight:
            value -= self.p.distance_weight * min(math.hypot(x - pose[0], y - pose[1])
                                                  for x, y in places)
        return value

    def _become(self, task: str, now: float, out: list[Say], changes: list[Change], why: str) -> None:
        self.task, self.since, self.last_claim, self.stalled_since = task, now, now, None
        self.held_since[task] = now
        out.append(Say("claim", dict(task_id=task, since=now, lease=self.p.lease_timeout)))
        changes.append(Change("won", task, why))

    def _release(self, reason: str, now: float, out: list[Say], changes: list[Change]) -> None:
        task = self.task
        self.task = None
        self.held_until[task] = max((lease.expiry() for lease in self.leases[task].values()),
                                    default=now)
        out.append(Say("release", dict(task_id=task, reason=reason)))
        changes.append(Change("released", task, reason))

    def _take_awards(self, now: float, out: list[Say], changes: list[Change]) -> None:
        awards, self._awards = self._awards, []
        awards.sort(key=lambda a: (-a[1].utility, a[1].task_id))
        for auctioneer, award, _ in awards:
            if self.task is None:
                self._become(award.task_id, now, out, changes,
                             f"won auction {auctioneer}#{award.auction} with {award.utility:.3g}")
            elif award.task_id != self.task:
                out.append(Say("release", dict(task_id=award.task_id,
                                               reason=f"busy with {self.task}")))

    def _take_revocations(self, now: float, out: list[Say], changes: list[Change]) -> None:
        revocations, self._revocations = self._revocations, []
        for auctioneer, msg in revocations:
            if self.task == msg.task_id and self.since == msg.since:
                timeout = self.tasks[msg.task_id].progress_timeout
                self.cooldown[msg.task_id] = now + timeout
                self._release(f"revoked by {auctioneer}: not done within its progress_timeout "
                              f"{timeout:g} s", now, out, changes)

    def _monitor(self, now: float, out: list[Say]) -> None:
        """Revoke the contracts of the tasks this robot serves that have run past their
        progress_timeout (module docstring): rank k among the task's other live servers waits
        k more reannounce_periods, so a revocation heard meanwhile makes it unnecessary."""
        for task in self.subjects:
            contracts = self.contracts[task]
            timeout = self.tasks[task].progress_timeout
            for holder, (since, first) in sorted(contracts.items()):
                if holder not in self.leases[task]:
                    continue  # lapsed: the lease rule auctions it
                monitors = sorted(((self.servers[task] & self.teammates) | {self.id}) - {holder})
                wait = monitors.index(self.id) * self.p.reannounce_period
                if now - first < timeout + wait - EPSILON:
                    continue
                reason = f"no progress: held {now - first:.1f} s, progress_timeout {timeout:g} s"
                out.append(Say("revoke", dict(task_id=task, holder=holder, since=since,
                                              reason=reason)))
                self._end_contract(task, holder, since, now)

    def _keep_or_release(self, now: float, readings: Readings, out: list[Say],
                         changes: list[Change]) -> None:
        if self.task is None:
            return
        earlier = [(lease.since, r) for r, lease in self.leases[self.task].items()
                   if lease.renewed and (lease.since, r) < (self.since, self.id)]
        if earlier:
            since, robot = min(earlier)
            self._release(f"duplicate: {robot} holds it since {since:.2f}", now, out, changes)
            return
        if readings.done(self.task, now):
            # served: given back at once, so the interval its claims and release draw ends
            # where the service did (not give_up_delay later, when a done task's evaluator —
            # inapplicable from then on — would have looked like a stall)
            self._release("done", now, out, changes)
            return
        if self.progressing(self.task, now, readings):
            self.stalled_since = None
        else:
            if self.stalled_since is None:
                self.stalled_since = now
            if now - self.stalled_since >= self.p.give_up_delay - EPSILON:
                self.cooldown[self.task] = now + self.p.give_up_delay
                self._release(f"no progress for {now - self.stalled_since:.1f} s", now, out,
                              changes)
                return
        if now - self.last_claim >= self.p.renewal_period - EPSILON:
            self.last_claim = now
            out.append(Say("claim", dict(task_id=self.task, since=self.since,
                                         lease=self.p.lease_timeout)))

    def _bid(self, now: float, readings: Readings, out: list[Say]) -> None:
        pending, self._announcements = self._announcements, []
        if self.task is not None:
            return
        for auctioneer, ann, t in pending:
            if now > t + ann.bid_window + EPSILON or not self.capable(ann.task_id, now, readings):
                continue
            if not all(readings.fresh(r, now) for r in ann.resources):
                continue
            out.append(Say("bid", dict(auctioneer=auctioneer, auction=ann.auction,
                                       task_id=ann.task_id,
                                       utility=self.utility(ann.task_id, readings)), auctioneer))
            self.bids_sent[(auctioneer, ann.auction)] = (ann.task_id,
                                                         now + ann.bid_window + self.p.lease_timeout)

    def _close_auctions(self, now: float, readings: Readings, out: list[Say],
                        changes: list[Change]) -> None:
        closed = [a for a in self.open.values() if now >= a.deadline - EPSILON]
        if not closed:
            return
        for a in closed:
            del self.open[a.number]
        busy = {r for leases in self.leases.values() for r in leases} | set(self.awarded)
        if self.task is not None:
            busy.add(self.id)
        candidates = sorted((-u, robot, a.task_id, a.number) for a in closed
                            if self._unheld(a.task_id, now) for robot, u in a.bids.items()
                            if robot not in busy and not self.barred(a.task_id, robot, now))
        done_tasks: set[str] = set()
        for neg_u, robot, task, number in candidates:
            if task in done_tasks or robot in busy:
                continue
            done_tasks.add(task)
            busy.add(robot)
            out.append(Say("award", dict(auction=number, task_id=task, winner=robot,
                                         utility=-neg_u)))
            if robot != self.id:
                self.awarded[robot] = (task, now + self.p.lease_timeout)
            self.held_until[task] = max(self.held_until.get(task, now), now + self.p.lease_timeout)
            if robot == self.id:
                self._become(task, now, out, changes,
                             f"won its own auction #{number} with {-neg_u:.3g}")

    def _unheld(self, task: str, now: float) -> bool:
        return self.task != task and self.held_until.get(task, -math.inf) < now - EPSILON

    def rank(self, task_id: str) -> int:
        """This robot's place among the live teammates that serve `task_id`, and itself (0:
        the first to auction it). A robot counts while both its agent token and its subject
        token live (the runtime tells both)."""
        return sorted((self.servers[task_id] & self.teammates) | {self.id}).index(self.id)

    def _announce(self, now: float, readings: Readings, out: list[Say]) -> None:
        period = self.p.reannounce_period
        auctioning = {a.task_id for a in self.open.values()}
        for task in self.subjects:  # only what it hears: it must hear who else announced
            if task in auctioning or not self._unheld(task, now):
                continue
            wait = self.rank(task) * period
            unheld_since = max(self.held_until.get(task, self.start), self.start)
            if now < unheld_since + wait - EPSILON:
                continue
            last = self.last_announced.get(task)
            if last is not None and last >= unheld_since and now - last < period + wait - EPSILON:
                continue
            number, self.next_auction = self.next_auction, self.next_auction + 1
            auction = OpenAuction(number, task, now + self.p.bid_window)
            self.open[number] = auction
            self.last_announced[task] = now
            out.append(Say("announcement", dict(auction=number, task_id=task,
                                                resources=self.tasks[task].resources,
                                                bid_window=self.p.bid_window), task))
            if self.task is None and self.capable(task, now, readings):
                auction.bids[self.id] = self.utility(task, readings)
