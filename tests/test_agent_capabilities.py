"""Capabilities, not probing: every architecture's coordinator subclasses
`mrta_agent.runtime.coordinator.Coordinator` (no-op hooks, py_trees' `Behaviour` style), and
every clock answers `in_lockstep()` and `restarts` (mrta_zenoh.clock.Clock). A misspelt hook
is refused when its class is defined, instead of silently disabling its feature."""

from __future__ import annotations

import ast

import pytest

from mrta_agent.alliance.agent import AllianceCoordinator
from mrta_agent.murdoch.agent import MurdochCoordinator
from mrta_agent.runtime.coordinator import Coordinator, Say
from mrta_agent.runtime.loop import Agent
from mrta_agent.runtime.plugins import Plugins, heard_at
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import Clock, ManualClock, SimClock, WallClock
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from tests.harness import source_tree
from tests.harness.helpers import ROOT
from tests.test_murdoch_subjects import _RecordingBus


def test_a_misspelt_hook_is_refused_when_the_class_is_defined():
    with pytest.raises(TypeError, match="teammate_subjects.*did you mean 'teammate_subject'"):
        class Typo(Coordinator):  # noqa: F841 - its definition is the test
            def teammate_subjects(self, robot, subject, alive):
                pass
    with pytest.raises(TypeError, match="did you mean 'advertises'"):
        class Typo2(Coordinator):  # noqa: F841
            advertise = ("a",)

    class Fine(Coordinator):  # private helpers and names unlike any hook are its own business
        def _helper(self):
            pass

        def pose(self):
            pass


def test_the_shipped_coordinators_are_coordinators_and_say_what_they_hear():
    assert issubclass(AllianceCoordinator, Coordinator)
    assert issubclass(MurdochCoordinator, Coordinator)
    assert not AllianceCoordinator.hears_subjects()  # advertises none: no watch of teammates'
    assert MurdochCoordinator.hears_subjects()



def test_the_own_route_logics_are_route_logics_with_no_op_hooks():
    """SSI's auction and CBBA's bundle are `RouteLogic`s (the Coordinator's hooks and `route`,
    `served`), driven by the own-route adapter without probing: the defaults do nothing, and a
    misspelt route hook is refused when its class is defined like any other."""
    from mrta_agent.cbba.bundle import Cbba
    from mrta_agent.route.own_route import RouteLogic
    from mrta_agent.ssi.auction import Ssi
    assert issubclass(Ssi, RouteLogic) and issubclass(Cbba, RouteLogic)
    assert issubclass(RouteLogic, Coordinator)
    bare = RouteLogic()
    assert bare.route() == [] and bare.served("t1", 1.0) is None and list(bare.tick(0.0)) == []
    with pytest.raises(TypeError, match="routes.*did you mean 'route'"):
        class Typo(RouteLogic):  # noqa: F841 - its definition is the test
            def routes(self):
                return []


def test_a_say_builds_its_message_by_field_name():
    """One way to say: a Say's fields are named, so a misnamed or missing field fails where the
    message is built instead of landing, shifted, in its neighbour."""
    from mrta_agent.alliance.messages import InterRobotCommunication
    types = {"irc": InterRobotCommunication}
    said = Say("irc", dict(expected_duration=2.0, task_id="a")).message(types, Header("r", 1, 1))
    assert (said.task_id, said.expected_duration, said.active_since) == ("a", 2.0, -1.0)
    with pytest.raises(TypeError, match="expected_durration"):
        Say("irc", dict(task_id="a", expected_durration=2.0)).message(types, Header("r", 1, 1))
    with pytest.raises(TypeError, match="expected_duration"):
        Say("irc", dict(task_id="a")).message(types, Header("r", 1, 1))


def dispatch_by_name(tree: ast.AST) -> list[int]:
    """Lines where an attribute is looked up by a name built from text (`getattr(o, "on_" +
    kind)`), or a message type named `Out` is defined: a second way to hear or to say."""
    return [n.lineno for n in ast.walk(tree)
            if (isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
                and n.func.id in ("getattr", "hasattr") and len(n.args) >= 2
                and isinstance(n.args[1], (ast.BinOp, ast.JoinedStr)))
            or (isinstance(n, ast.ClassDef) and n.name == "Out")]


def test_one_way_to_say_and_to_hear_in_the_agent():
    assert dispatch_by_name(ast.parse('getattr(self.core, "on_" + kind)(sender, msg, at)')) \
        == [1]
    assert dispatch_by_name(ast.parse('class Out(NamedTuple):\n    kind: str')) == [1]
    bad = [f"{f.relative_to(ROOT)}:{line}" for f in source_tree.python_files(ROOT / "robot_agent")
           for line in dispatch_by_name(source_tree.tree(f))]
    assert not bad, bad


def message_types(trees) -> set[str]:
    """The names of the classes deriving from `Message` in `trees`, through any depth
    (`IndexedMessage`'s)."""
    classes = {n.name: {b.id for b in n.bases if isinstance(b, ast.Name)}
               for tree in trees for n in ast.walk(tree) if isinstance(n, ast.ClassDef)}
    found, grew = {"Message"}, True
    while grew:
        more = {name for name, bases in classes.items() if bases & found} - found
        found, grew = found | more, bool(more)
    return found - {"Message"}


def test_the_agent_builds_every_message_by_field_name():
    """Not `Bids(header, winners, stamps, ...)`: a field added or moved in the type would shift
    every value after it into its neighbour, silently (msgspec does not validate on build)."""
    sources = {f: source_tree.tree(f)  # parsed once per session (tests/harness/source_tree.py)
               for root in ("robot_agent", "mrta_zenoh")
               for f in source_tree.python_files(ROOT / root)}
    types = message_types(sources.values())
    assert {"Header", "Bids", "Progress", "Twist", "Assigned"} <= types
    bad = []
    for f, tree in sorted(sources.items()):
        if not f.is_relative_to(ROOT / "robot_agent"):
            continue
        # a file's own class of the same name is not the message (ssi's Award, murdoch's)
        here = types - {n.name for n in ast.walk(tree) if isinstance(n, ast.ClassDef)
                        and not {b.id for b in n.bases if isinstance(b, ast.Name)}
                        & (types | {"Message"})}
        bad += [f"{f.relative_to(ROOT)}:{n.lineno}: {n.func.id}" for n in ast.walk(tree)
                if isinstance(n, ast.Call) and isinstance(n.func, ast.Name)
                and n.func.id in here and n.args]
    assert not bad, bad

class _Tally(_RecordingBus):
    """What an agent declares and watches (tests/test_murdoch_subjects.py), and subscribes to."""

    def __init__(self):
        super().__init__()
        self.subscriptions = []

    def subscribe(self, key_expr, handler, msg_type=None, **kwargs):
        self.subscriptions.append(key_expr)
        return self._Handle()


class Bare(Coordinator):
    """Only what it needs: it hears one kind, says one thing, uses every other default."""

    listens = ("inter_robot_communication",)

    def tick(self, now):
        return [Say("inter_robot_communication",
                    dict(task_id="a", expected_duration=1.0, active_since=now))]


class Subjects(Bare):
    @property
    def advertises(self):
        return ("a",)

    def subjects(self, kind):
        return ("a", "b")

    def teammate_subject(self, robot, subject, alive):
        pass


@pytest.mark.parametrize("coordinator, watches, subscriptions, tokens", [
    (Bare, ["*/alliance/agent"], ["*/alliance/inter_robot_communication"],
     ["robot1/alliance/agent"]),
    (Subjects, ["*/alliance/subject/*", "*/alliance/agent"],
     ["*/alliance/inter_robot_communication/a", "*/alliance/inter_robot_communication/b"],
     ["robot1/alliance/subject/a", "robot1/alliance/agent"])])
def test_the_driver_asks_every_hook_and_the_defaults_cost_nothing(coordinator, watches,
                                                                  subscriptions, tokens):
    from mrta_agent.alliance.architecture import ALLIANCE
    bus = _Tally()
    agent = Agent("robot1", ALLIANCE, coordinator, bus, ManualClock(0.0), None,
                  Plugins([], [], {}, None), 10.0, 10.0)
    agent.start()
    agent.declare_alive()
    assert (bus.watches, bus.subscriptions, bus.tokens) == (watches, subscriptions, tokens)
    assert agent.coordinator.active_task is None and agent.active_task is None
    assert agent.coordinator.hear("inter_robot_communication", "robot2", None, 0.0) is False


def test_every_clock_answers_its_capabilities():
    for clock in (WallClock(), ManualClock(), SimClock()):
        assert isinstance(clock, Clock) and not clock.in_lockstep() and clock.restarts == 0
    lockstep = LockstepClock("robot1")
    assert not lockstep.in_lockstep()
    lockstep.lockstep.set()  # what the participant does on the first step it takes
    assert lockstep.in_lockstep()
    sim = SimClock(wall=lambda: 100.0)
    sim.on_clock(5.0, "run-a")
    sim.source_lost("run-a")
    sim.on_clock(0.1, "run-b")  # a new run: time restarted
    assert sim.restarts == 1


def test_a_sample_counts_at_its_stamp_only_in_lockstep():
    odom = Odometry(Header("robot1", 3.5, 1), Pose2D(0.0, 0.0, 0.0), Twist(0.0, 0.0))
    clock = LockstepClock("robot1")
    clock.set(4.0)
    assert heard_at(clock, odom) == 4.0  # not in lockstep: when it arrived
    clock.lockstep.set()
    assert heard_at(clock, odom) == 3.5  # in lockstep: its own stamp, whatever step it is
    assert heard_at(clock, Twist(0.0, 0.0)) == 4.0  # no header: when it arrived


def test_the_loop_starts_afresh_when_its_clock_restarts():
    """The driver reads `restarts` from any clock (no probing): a change is a new run."""
    from mrta_agent.alliance.architecture import ALLIANCE
    built = []

    class Counting(Bare):
        def __init__(self):
            built.append(self)

    clock = ManualClock(0.0)
    agent = Agent("robot1", ALLIANCE, Counting, InProcBus(), clock, None,
                  Plugins([], [], {}, None), 10.0, 10.0)
    loop = agent.schedule(None)
    clock.set(next(loop))
    clock.set(next(loop))
    assert len(built) == 1
    clock.restarts = 1
    clock.set(0.05)
    clock.set(next(loop))
    assert len(built) == 2  # the decision logic built afresh
