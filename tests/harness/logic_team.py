"""A team of pure decision logics (SSI's `Ssi`, CBBA's `Cbba`) exchanging their real message
objects in virtual time, as the agent runtime would deliver them in lockstep: what a robot says
at tick t is heard by the others at their tick t + dt, stamped t, with headers carrying sender,
time and a per-sender sequence number. Robots can leave (every other one is told, as a token
going), messages can be lost (by a seeded rule) or be out of range (`neighbours`)."""

from __future__ import annotations

import random
from typing import Callable

from mrta_zenoh.messages import Header


class LogicTeam:
    def __init__(self, logics: dict, messages: dict, dt: float = 0.1, start: float = 0.0,
                 neighbours: Callable[[str, str], bool] | None = None, loss: float = 0.0,
                 seed: int = 0):
        self.logics = dict(logics)
        self.messages = messages
        self.dt, self.now = dt, start
        self.neighbours = neighbours or (lambda a, b: True)
        self.loss, self.rng = loss, random.Random(seed)
        self.inbox: dict[str, list] = {r: [] for r in self.logics}
        self.seq: dict[str, int] = {}
        self.sent: list[tuple[str, object]] = []  # every message said, in order
        self.dropped = 0
        self.refused = 0
        for logic in self.logics.values():
            for other in self.logics:
                logic.teammate(other, True)

    def step(self) -> int:
        """One tick of every robot (in id order); returns how many messages were said."""
        said = []
        for robot, logic in sorted(self.logics.items()):
            for kind, msg in self.inbox[robot]:
                if not logic.hear(kind, msg.header.frame_id, msg, msg.header.stamp):
                    self.refused += 1
            self.inbox[robot] = []
            for out in logic.tick(self.now):
                self.seq[robot] = self.seq.get(robot, 0) + 1
                msg = out.message(self.messages, Header(robot, self.now, self.seq[robot]))
                said.append((robot, out, msg))
        for robot, out, msg in said:
            self.sent.append((out.kind, msg))
            for other in self.logics:
                if other == robot or (out.subkey is not None and out.subkey != other):
                    continue
                if not self.neighbours(robot, other):
                    continue
                if self.loss and self.rng.random() < self.loss:
                    self.dropped += 1
                    continue
                self.inbox[other].append((out.kind, msg))
        self.now += self.dt
        return len(said)

    def run(self, quiet: int = 5, max_steps: int = 5_000, until: float | None = None) -> None:
        """Step until `quiet` ticks in a row said nothing (and, with `until`, time has reached
        it). RuntimeError if it never quiets down."""
        calm = 0
        for _ in range(max_steps):
            calm = 0 if self.step() else calm + 1
            if calm >= quiet and (until is None or self.now >= until):
                return
        raise RuntimeError(f"the team still talks after {max_steps} ticks")

    def leave(self, robot: str) -> None:
        """`robot` stops (its token goes): it is told nothing more, the others learn it left."""
        del self.logics[robot]
        del self.inbox[robot]
        for logic in self.logics.values():
            logic.teammate(robot, False)

    def deliver(self, robot: str, kind: str, msg) -> bool:
        return self.logics[robot].hear(kind, msg.header.frame_id, msg, msg.header.stamp)
