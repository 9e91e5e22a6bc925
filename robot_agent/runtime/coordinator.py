"""What an architecture gives the agent driver: its decision logic for one robot (`Coordinator`)
and what that logic says (`Say`).

`Coordinator` is a base class with a no-op default for every hook, as py_trees' `Behaviour` is:
the driver calls every hook on every coordinator, so a capability an architecture does not use
costs it nothing, and one it does use is never found by probing. A subclass whose public name
is one edit away from a hook's (`teammate_subjects`) is refused when its class is defined: with
probing, such a typo silently disabled the feature.
"""

from __future__ import annotations

import collections
import difflib
from typing import TYPE_CHECKING, Any, ClassVar, Iterable, Mapping, NamedTuple

from mrta_zenoh.messages import Header, Message

if TYPE_CHECKING:
    from .growth import Growth


class Say(NamedTuple):
    """One message the decision logic wants sent: its kind (a key chunk under the
    architecture's namespace, with an optional sub-key), the fields after the header *by name*
    (a field added, renamed or moved in the message type fails where the message is built, not
    silently shifted into its neighbour), and whether it may be dropped under pressure
    (monitoring) or must arrive (coordination), and whether it is for observers only
    (`watched`: the supervisor, the recorder, the plots — no teammate's decision reads it, so
    lockstep holds no step for it: Bus.leave_unclaimed)."""

    kind: str
    fields: Mapping[str, Any]
    subkey: str | None = None
    lossy: bool = False
    watched: bool = False

    def message(self, types: Mapping[str, type[Message]], header: Header,
                **stamped: Any) -> Message:
        """The message said, of its kind's type in `types` (an architecture's `messages`), with
        the fields the driver stamps on it besides the header (`stamped`: an indexed message's
        instance digest, which the logic does not know)."""
        return types[self.kind](header=header, **self.fields, **stamped)


class Coordinator:
    """An architecture's decision logic for one robot, driven by `mrta_agent.runtime.loop.Agent`.

    * `listens`: the message kinds it hears from teammates; `subjects(kind)`: the sub-keys of
      `kind` it hears (`*/<namespace>/<kind>/<subject>` for each), or None (the default) for
      every robot's — MURDOCH hears only the announcements of the tasks it serves and the bids
      addressed to it;
    * `hear`: one message from a teammate (sender checked) at the time it counts as heard;
      whether it accepted it;
    * `teammate(robot, alive)`: a teammate's agent token came or went;
    * `advertises`: subjects this robot tells its teammates about with a liveliness token each
      (`robotN/<namespace>/subject/<subject>`, declared just before its agent token), and
      `teammate_subject(robot, subject, alive)`: a teammate's subject came or went — told at the
      decision step, like `teammate`, for teammates only: a subject counts while both its token
      and the robot's agent token live. MURDOCH advertises the tasks a robot serves, so the
      auctioneer of a task is ranked among the robots that serve it; ALLIANCE advertises none;
    * `tick(now)`: the decision step, what to send;
    * `active_task`: the task whose layers run (None: none);
    * `refuse(kind, sender, reason)`: what a logic did not believe of a message it accepted
      otherwise (a claim its sender cannot make: docs/security.md), counted by kind, sender and
      reason — the driver reports these with the messages `hear` refused whole
      (`refusals()`), so every summary shows what was refused;
    * tasks at run time (runtime/growth.py, issue 50), told at the decision step after the
      instant each entered, before `tick`: `tasks_added(growth, now)` — tasks submitted (the
      robot's instance and plugins already hold them; `growth.problem(p)` grows a planning
      problem); `task_priority(task, priority, now)` — a new priority; `task_cancelled(task,
      now)` — withdrawn (the robot's evaluators say so already: a logic that plans for others,
      central's dispatcher, drops it). No-ops by default: a logic that ignores them serves no
      submitted task (the intake refuses submissions for such an architecture:
      `Architecture.takes_submitted`).
    """

    listens: ClassVar[tuple[str, ...]] = ()
    HOOKS: ClassVar[tuple[str, ...]] = ("listens", "subjects", "hear", "teammate", "advertises",
                                        "teammate_subject", "tick", "active_task",
                                        "hears_subjects", "tasks_added", "task_priority",
                                        "task_cancelled")

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        for name in vars(cls):
            if name.startswith("_") or name in cls.HOOKS:
                continue
            close = difflib.get_close_matches(name, cls.HOOKS, n=1, cutoff=0.85)
            if close:
                raise TypeError(f"{cls.__qualname__}.{name}: not a Coordinator hook — did you "
                                f"mean {close[0]!r}? (the driver would never call it)")

    def refuse(self, kind: str, sender: str, reason: str, forged: bool = True) -> None:
        """Count one refused claim (class docstring); `forged`: no process of the run would
        say it (mrta_zenoh/refusal_tally.py), False for what an honest team says under faults.
        Senders are teammates the driver admitted (or, for a dispatcher, robots of the
        instance), reasons a logic's constants: the count stays bounded whatever is sent."""
        counts = vars(self).setdefault("_refusals", collections.Counter())
        counts[(kind, sender, reason, forged)] += 1

    def refusals(self) -> Mapping[tuple[str, str, str, bool], int]:
        """(kind, sender, reason, forged) → how many claims the logic refused (`refuse`)."""
        return vars(self).get("_refusals", {})

    @classmethod
    def hears_subjects(cls) -> bool:
        """Whether it overrides `teammate_subject`: only then does the driver watch teammates'
        subject tokens (one watch per agent, which ALLIANCE, advertising none, does without)."""
        return cls.teammate_subject is not Coordinator.teammate_subject

    @property
    def active_task(self) -> str | None:
        return None

    @property
    def advertises(self) -> tuple[str, ...]:
        return ()

    def subjects(self, kind: str) -> tuple[str, ...] | None:
        return None

    def hear(self, kind: str, sender: str, message, at: float) -> bool:
        return False

    def teammate(self, robot: str, alive: bool) -> None:
        pass

    def teammate_subject(self, robot: str, subject: str, alive: bool) -> None:
        pass

    def tick(self, now: float) -> Iterable[Say]:
        return ()

    def tasks_added(self, growth: Growth, now: float) -> None:
        pass

    def task_priority(self, task_id: str, priority: int, now: float) -> None:
        pass

    def task_cancelled(self, task_id: str, now: float) -> None:
        pass
