"""CBBA in the paper's synchronous rounds (Choi et al. 2009, §IV-C): in round r every robot
applies the messages its neighbours sent in round r − 1, releases and builds its bundle, and
sends its state to its neighbours. This is the model of the paper's convergence theorem, run on
the same `Cbba` logic the agents run; tests and benchmarks drive it, an agent never does.

A round's time stamp is its number, so time stamps grow with every round as the paper's
iteration counter does; planning time does not move (each robot's route still starts at its
origin), so every round scores the same instance.
"""

from __future__ import annotations

import time
from typing import Callable, Mapping

from mrta_zenoh.messages import Header

from .bundle import Cbba
from .messages import MESSAGES

Neighbours = Callable[[str, str], bool]


def full(a: str, b: str) -> bool:
    return True


def state(team: Mapping[str, Cbba]) -> tuple:
    """What convergence is about: every robot's winners, bids, bundle and path."""
    return tuple((r, tuple(c.z), tuple(c.y), tuple(c.bundle), tuple(c.path))
                 for r, c in sorted(team.items()))


def run_rounds(team: Mapping[str, Cbba], neighbours: Neighbours = full, max_rounds: int = 10_000,
               start: int = 1, quiet: int | None = None,
               timings: list[tuple[int, str, float]] | None = None) -> int:
    """Run rounds `start`, `start` + 1, … until `quiet` rounds in a row change nothing (default:
    as many as robots, more than the network's diameter: time stamps, which some rows of Table 1
    compare, need that long to travel), at most `max_rounds` of them. Returns the last round that
    changed something (`start` − 1 if none did). RuntimeError if the team did not settle.
    `timings`, if given, gets (round, robot, seconds) of each robot's iteration: the messages
    it heard and its tick (benchmarks/cbba.py)."""
    quiet = len(team) if quiet is None else quiet
    seq = {r: 0 for r in team}
    inbox: dict[str, list] = {r: [] for r in team}
    last_change = start - 1
    for rnd in range(start, start + max_rounds):
        before = state(team)
        outbox = []
        for robot, logic in sorted(team.items()):
            began = time.perf_counter()
            for kind, message in inbox[robot]:
                logic.hear(kind, message.header.frame_id, message, float(rnd))
            inbox[robot] = []
            said = logic.tick(float(rnd))
            if timings is not None:
                timings.append((rnd, robot, time.perf_counter() - began))
            for out in said:
                seq[robot] += 1
                header = Header(frame_id=robot, stamp=float(rnd), seq=seq[robot])
                outbox.append((robot, out.kind, out.message(MESSAGES, header)))
        for sender, kind, message in outbox:
            for robot in team:
                if robot != sender and neighbours(sender, robot):
                    inbox[robot].append((kind, message))
        if state(team) != before:
            last_change = rnd
        elif rnd >= last_change + quiet:
            return last_change
    raise RuntimeError(f"CBBA did not settle within {max_rounds} rounds")
