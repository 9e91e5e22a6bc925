"""The architecture contract: what tools and applications may ask of an MRTA architecture, and
the registry (`mrta.architectures`) that finds the installed ones.

rqt_mrta registered an architecture as a package of XML (its monitors and templates); the tools
that measure a run need more than that — which command runs a robot, how long a takeover may
take, who is doing which task *according to the robots themselves*. An architecture is one
object registered under the entry-point group `mrta.architectures`; the mission runner,
`mrta experiment`, the plots and an application's plugins (patrol's ledger) reach it only through
this class, so a third architecture needs no edit of any application. The core defines the
contract and knows no architecture (pluginlib's base class, not a plugin). Faults are not part
of it: they are injected the same way for every architecture (mrta_zenoh.failure, the fault
channel, and the agent runtime's driver).

The agent side of an architecture (how its decision logic is built and driven) lives beside the
agent runtime, `mrta_agent.runtime.architecture.AgentArchitecture`, which extends this class.
"""

from __future__ import annotations

import threading
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, ClassVar, Iterable, Sequence

from .clock import EPSILON
from .errors import ConfigError
from .failure import Faults
from .installed import entry_points
from .untrusted import visible
from .keys import NODE_TOKEN, first_chunk
from .yamlfile import did_you_mean

GROUP = "mrta.architectures"
# ROBOT,ROBOT,…: an agent's `--team` (robot_agent/runtime/cli.py). Every robot launch file sets
# it to the application's robots (toolchain/generator.py), so an agent counts only them,
# whatever architecture it runs (a verb that knows no team ignores it).
TEAM_ENV = "MRTA_TEAM"


@dataclass(frozen=True)
class Doing:
    """One report read from an architecture's own wire message: at `stamp` (the sender's clock:
    simulated time in simulated runs), `robot` was on `task` (active) or was not (inactive).
    An architecture whose robots hold queues (routes of tasks served one after another) also
    says the tasks queued behind it (`queue`, the robot's whole queue as it held it then);
    None: it keeps no queue (a robot is assigned what it is on)."""

    robot: str
    task: str
    active: bool
    stamp: float
    queue: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Decision:
    """One allocation decision as an architecture's own message records it: when (`stamp`,
    the decider's clock), by whom, and how long its computation took (`ms`, the machine's
    time: a measurement, never a criterion)."""

    decider: str
    stamp: float
    ms: float
    objective: str | None = None  # the objective it optimised (planning.schedule.Objective)
    # what names it across repeats of its message (a message resent until acknowledged records
    # one decision, counted once); None: every message is a decision of its own
    ident: object = None
    # its search was stopped by a time cap: what it decided depends on the machine's speed
    capped: bool = False
    # the robots the decider had left out of its plan then, and why ((robot, "stalled"), …):
    # what it declared (a stall, a silence) is in the summary, from when until when
    out: tuple[tuple[str, str], ...] = ()
    # False: no decision of its own (a repeat, a Round that awards nothing, a resent table),
    # read only for what it says of who is left out (`out`)
    counted: bool = True


MAX_OUT = 64  # `robot:reason` statements of one message read (a team leaves out fewer)


def declared_out(out: Iterable[str]) -> tuple[tuple[str, str], ...]:
    """`Decision.out` from a message's `robot:reason` strings (central's `Plan.out`, SSI's
    `Round.out`, CBBA's `Bids.out`); a string without a reason is no statement, and skipped.
    They come from the bus: the first MAX_OUT only, their names escaped and cut (untrusted.py),
    so a forged message can neither swell a summary nor write to its reader's terminal."""
    said = [o.split(":", 1) for o in out if ":" in o][:MAX_OUT]
    return tuple((visible(robot, 40), visible(reason, 40)) for robot, reason in said)


@dataclass(frozen=True)
class Takeover:
    """One takeover as a run's recording shows it, for `Architecture.takeover_check`: `failed`
    stopped doing `task` at `failed_at` (its fault began) and `taker` began it at `taken_at`
    (run seconds, from the robots' own reports)."""

    task: str
    failed: str
    failed_at: float
    taker: str
    taken_at: float
    robot_params: Path                 # the taker's parameter file
    records: Sequence                  # the recording: (key, encoding, log time, payload)
    time_of: Callable[[int], float]    # a record's log time → run seconds
    faults: Faults                     # every fault the run injected
    seed: int                          # the run's seed (the faults' draws derive from it)
    lockstep: bool                     # in lockstep a message counts as heard at its stamp


@dataclass(frozen=True)
class TakeoverBound:
    """An architecture's bound on one takeover, in the case the run was in."""

    seconds: float | None   # None: no bound holds in this case (`case` says why)
    since: float            # the instant it counts from (run seconds)
    since_what: str = ""    # that instant for people; "" when it is the fault itself
    case: str = ""          # the condition the bound rests on, as this run met it

    def holds(self, taken_at: float) -> bool | None:
        """Whether a takeover at `taken_at` is within the bound (None: there is none)."""
        if self.seconds is None:
            return None
        return taken_at - self.since <= self.seconds + EPSILON


class Architecture(ABC):
    """An MRTA architecture as tools see it. Subclasses set the class attributes and implement
    `doing` and `takeover_bound`; everything else has a default every architecture built on
    mrta_agent's runtime shares."""

    name: ClassVar[str]            # registry name = its rqt_mrta package name ("alliance")
    title: ClassVar[str]           # for people ("ALLIANCE")
    namespace: ClassVar[str]       # coordination keys: robotN/<namespace>/<kind>
    executable: ClassVar[str]      # a launch file's pkg/type for one robot ("robot_agent/agent")
    command: ClassVar[str]         # its `mrta` verb ("agent")
    param_stem: ClassVar[str]      # parameter files: robot1_<stem>_params.yaml, tasks_<stem>_…
    bound_formula: ClassVar[str]   # the takeover bound as people write it
    messages: ClassVar[dict[str, type]]  # kind → message type, published on robotN/<ns>/<kind>[/…]
    doing_kinds: ClassVar[tuple[str, ...]]  # the kinds `doing` reads
    # The kinds robots tell each other — coordination proper, what a study counts as its cost
    # — a subset of `messages`; None: every kind. What an architecture publishes for people
    # and tools to watch (ALLIANCE's Motivation and SensoryFeedback panels) is bus traffic,
    # not coordination: counting it would make ALLIANCE look 40 times as chatty as it is.
    coordination_kinds: ClassVar[tuple[str, ...] | None] = None
    # a robot on a task repeats so at least this often (seconds of its clock): a report not
    # repeated for longer means it stopped without saying so (it died)
    doing_stale_after: ClassVar[float] = 2.0
    # the processes of a run that are neither robot nor observer (central's dispatcher): each
    # declares `process_token(name)` once ready, robots take its messages as a teammate's, and
    # a run's faults may name it (`crash:dispatcher@T`). Default: none
    processes: ClassVar[tuple[str, ...]] = ()
    # the objective it optimises (planning.schedule.Objective's value: minsum, makespan,
    # flowtime), which a run's summary names; None: it states none (ALLIANCE, MURDOCH)
    objective: ClassVar[str | None] = None
    # the kinds `decision` reads: messages that record an allocation decision. Default: none
    decision_kinds: ClassVar[tuple[str, ...]] = ()
    # whether its robots serve tasks submitted at run time (issue 50: its logic grows through
    # the Coordinator's `tasks_added`); False — a run's intake refuses every submission, saying
    # why (`submitted_refusal`). Default: False
    takes_submitted: ClassVar[bool] = False
    # whether it runs a mission whose tasks are continuous — never done (patrol's wander and
    # border). False for an architecture whose robots serve routes of tasks that end (central,
    # SSI, CBBA, TeSSI): a continuous task would head a route forever, and their planners need
    # an instance's point tasks. A patrol package for one ran with idle robots and no
    # dispatcher (issue 51, the newcomer's list); it is refused, naming why. Default: True
    continuous_tasks: ClassVar[bool] = True

    def mission_refusal(self, mission: str, continuous: bool) -> str:
        """Why this architecture cannot run `mission` ("" when it can): `continuous`, whether
        the mission's tasks are continuous (`Mission.continuous`)."""
        if self.continuous_tasks or not continuous:
            return ""
        able = [n for n, a in architectures().items() if a.continuous_tasks]
        return (f"the {mission} mission's tasks are continuous (never done) and {self.title}'s "
                f"robots serve routes of tasks that end: run {mission} under "
                f"{' or '.join(able) or 'another architecture'} (docs/central.md, \"Patrol\")")

    def submitted_refusal(self) -> str:
        """Why a run of this architecture refuses submitted tasks ("" when it takes them)."""
        if self.takes_submitted:
            return ""
        return (f"{self.title} serves no task submitted at run time (its robots' task sets are "
                "fixed at start-up: docs/tasks.md)")

    # ------------------------------------------------------------ keys
    def key(self, robot_id: str, kind: str, *rest: str) -> str:
        """`robot1/alliance/motivation/wander`: where `robot_id` says `kind` (and its sub-key)."""
        return "/".join((robot_id, self.namespace, kind, *rest))

    def every(self, kind: str) -> str:
        """Every robot's `kind` messages, sub-keys included: `*/murdoch/claim`, `*/alliance/motivation/**`."""
        return f"*/{self.namespace}/{kind}" + ("/**" if self.has_subkeys(kind) else "")

    def has_subkeys(self, kind: str) -> bool:
        """Whether `kind` is published under one more chunk (ALLIANCE's motivation/<task>)."""
        return False

    def agent_token(self, robot_id: str) -> str:
        """The liveliness token a robot's agent declares once it is ready (alive means ready)."""
        return self.key(robot_id, "agent")

    @property
    def agent_tokens(self) -> str:
        """Every robot's agent token: `*/alliance/agent`."""
        return f"*/{self.namespace}/agent"

    def process_token(self, name: str) -> str:
        """The liveliness token process `name` (one of `processes`) declares once ready:
        `@mrta/node/<name>` — under `@`, so no robot watch takes it for a robot."""
        return f"{NODE_TOKEN}/{name}"

    @property
    def coordination(self) -> tuple[str, ...]:
        """The kinds that are coordination: `coordination_kinds`, or every kind of `messages`."""
        if self.coordination_kinds is None:
            return tuple(self.messages)
        return tuple(self.coordination_kinds)

    def is_coordination_key(self, key: str) -> bool:
        """Whether a sample on `key` is one robot telling the others something:
        `robot1/<namespace>/<kind>[/sub-key…]` with `kind` among `coordination`
        (`robot1/murdoch/announcement/t1` is; ALLIANCE's `robot1/alliance/motivation/t1` is not)."""
        chunks = key.split("/")
        return len(chunks) > 2 and chunks[1] == self.namespace and chunks[2] in self.coordination

    def is_namespace_key(self, key: str) -> bool:
        """Whether `key` is one of the architecture's messages, coordination or monitoring."""
        chunks = key.split("/")
        return len(chunks) > 2 and chunks[1] == self.namespace and chunks[2] in self.messages

    # ------------------------------------------------------------ who is doing what
    def doing_feed(self) -> list[tuple[str, type]]:
        """(key expression, message type) pairs to subscribe to for `doing`."""
        return [(self.every(kind), self.messages[kind]) for kind in self.doing_kinds]

    def read_doing(self, key: str, message: object) -> Doing | None:
        """`doing` for a sample of the feed, after the sender check every architecture needs:
        the key's first chunk must be the robot its header names (a sample on robot1's key
        claiming to be robot2 says nothing)."""
        sender = first_chunk(key)
        header = getattr(message, "header", None)
        if header is None or header.frame_id.strip("/") != sender:
            return None
        return self.doing(sender, key, message)

    @abstractmethod
    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        """What a sample of the feed says `sender` is doing (None: nothing about tasks)."""

    def decision_feed(self) -> list[tuple[str, type]]:
        """(key expression, message type) pairs to subscribe to for `decision`."""
        return [(self.every(kind), self.messages[kind]) for kind in self.decision_kinds]

    def decision(self, sender: str, key: str, message: object) -> Decision | None:
        """The allocation decision a sample of `decision_feed` records (None: none). Default:
        none — an architecture whose decisions leave no record of their computation time."""
        return None

    # ------------------------------------------------------------ what a run is measured against
    @abstractmethod
    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """The longest a robot with these parameters takes to pick up `task` after the robot
        doing it stops (seconds of its clock)."""

    def takeover_check(self, takeover: Takeover) -> TakeoverBound:
        """The bound a run's takeover is checked against, counted from the instant it holds
        from and with the condition it rests on (what the mission summary reports). Default:
        `takeover_bound`, counted from the fault, with no condition."""
        return TakeoverBound(self.takeover_bound(takeover.robot_params, takeover.task),
                             takeover.failed_at)

    # ------------------------------------------------------------ checking files
    def check_files(self, robot_id: str, robot_params: Path, tasks_params: Path,
                    layers_params: Path | None = None) -> None:
        """Read and check one robot's parameter files as its agent would at start (ConfigError
        naming file, line and key), without starting anything: what `mrta experiment` runs on
        every overridden value before the first run. Default: nothing to check."""

    def layer_sections(self, robot_id: str, robot_params: Path,
                       tasks_params: Path) -> frozenset[str] | None:
        """The sections of the layers file this robot's plugins read: what `mrta app new`
        asks for and writes (a section no plugin reads is a warning at every start). Default:
        None, not known — every section of the template is asked for."""
        return None

    # ------------------------------------------------------------ optional extras
    def plots(self, recording: Path, robots: list[str], tasks: list[str], output: Path,
              records: list | None = None) -> list[str]:
        """Architecture-specific pictures of a recorded run written into `output` (ALLIANCE's
        motivation panels); the names of the files written. Default: none."""
        return []

    def __repr__(self) -> str:
        return f"<architecture {self.name}>"


_lock = threading.RLock()  # re-entrant: an architecture built on another may look it up on import
_loaded: dict[str, Architecture] = {}


def _entry_points() -> dict:
    return {ep.name: ep for ep in entry_points(group=GROUP)}


def architecture_names() -> list[str]:
    return sorted(_entry_points())


def architecture(name: str) -> Architecture:
    """The registered architecture `name`; ConfigError with the registered names otherwise.
    Only this one entry point is loaded, so a broken third-party package cannot stop the
    others from running."""
    with _lock:
        if name in _loaded:
            return _loaded[name]
        eps = _entry_points()
        ep = eps.get(name)
        if ep is None:
            raise ConfigError(f"no architecture {name!r} is registered (entry-point group "
                              f"{GROUP}: {', '.join(sorted(eps)) or 'none'})"
                              + did_you_mean(name, eps))
        try:
            arch = ep.load()
        except Exception as exc:  # a third party's import-time failure, whatever it is
            raise ConfigError(f"architecture {name!r} ({ep.value}) cannot be loaded: "
                              f"{type(exc).__name__}: {exc}") from exc
        if isinstance(arch, type):
            arch = arch()
        if not isinstance(arch, Architecture):
            raise ConfigError(f"architecture {name!r} ({ep.value}) is a {type(arch).__name__}, "
                              "not an mrta_zenoh.architectures.Architecture")
        if arch.name != name:
            raise ConfigError(f"architecture registered as {name!r} ({ep.value}) calls itself "
                              f"{arch.name!r}")
        unknown = sorted(set(arch.coordination) - set(arch.messages))
        if unknown:
            raise ConfigError(f"architecture {name!r} ({ep.value}): coordination_kinds "
                              f"{', '.join(unknown)} are not among its messages "
                              f"({', '.join(sorted(arch.messages))})")
        _loaded[name] = arch
        return arch


def architectures() -> dict[str, Architecture]:
    """Every registered architecture, by name."""
    return {name: architecture(name) for name in architecture_names()}
