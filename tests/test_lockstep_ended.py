"""A member's participant token proves nothing once the member's process has ended (issue 51):
Zenoh shows one token per key however many sessions declare it, so a forger's token under
robot1's name kept the name alive after robot1's process ended, and the barrier waited for it
its whole timeout (30 s; with forged work beats, WORK_LIMIT timeouts). The run's runner says
which members ended through a file (mrta_zenoh/lockstep/ended.py); a token that outlives its process is the simulator's refusal,
forged, in the summary. The barrier on the in-process bus (which conflates tokens as Zenoh does) with a hand-moved wall clock."""

from __future__ import annotations

import threading

from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import run_id
from mrta_zenoh.keys import CLOCK_SOURCE_TOKEN
from mrta_zenoh.lockstep.barrier import Barrier
from mrta_zenoh.lockstep.ended import EndedWatch, read_ended
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.lockstep.protocol import DONE, OUTLIVED_AFTER, PARTICIPANT, StepDone
from mrta_zenoh.refusal_tally import RefusedTally, refused_key
from tests.harness.helpers import Wall, wait_for
from tests.test_lockstep_exact import in_thread


def test_a_members_token_that_outlives_its_process_is_not_waited_for():
    net, wall, stop = InProcNetwork(), Wall(), threading.Event()
    ended: set[str] = set()
    sim_bus, forger = InProcBus(net), InProcBus(net)
    run = run_id(0)
    barrier = Barrier(sim_bus, run, 30.0, wall=wall, members=frozenset({"robot1", "robot2"}),
                      ended=lambda: frozenset(ended))
    source = sim_bus.declare_token(f"{CLOCK_SOURCE_TOKEN}/{run}")
    tallies: list = []
    sim_bus.subscribe(refused_key("simulator"), tallies.append, msg_type=RefusedTally)
    clock = LockstepClock("robot1", wall=wall)
    stack = clock.join(InProcBus(net))
    try:
        wait_for(lambda: "robot1" in barrier.participants)
        token = forger.declare_token(f"{PARTICIPANT}/robot1")  # the forger's, beside robot1's
        barrier.publish(0.0)
        stepped = in_thread(lambda: barrier.wait(0.0, stop))
        in_thread(lambda: clock.sleep_until(0.1, stop))
        wait_for(stepped.is_set)                   # robot1 answers step 0
        stack.close()                              # robot1's process ends: its token goes...
        assert barrier.participants == {"robot1"}  # ...and the forger's keeps the name alive
        barrier.publish(0.1)
        stepped = in_thread(lambda: barrier.wait(0.1, stop))
        wait_for(lambda: barrier._stamp is not None)
        wall.t += 1.0                              # late, not yet said to have ended
        for _ in range(3):                         # forged beats would keep it waited for, too
            forger.publish(f"{DONE}/robot1", StepDone("robot1", 0.1, {}, 0.2, run, working=True))
        assert not stepped.wait(0.2)
        ended.add("robot1")                        # the runner saw its process end
        wall.t += 0.5
        wait_for(stepped.is_set)                   # not the timeout: ENDED_AFTER
        assert set(barrier.gone) == {"robot1"} and barrier.given_up == 0  # the run stays exact
        dropped = barrier.dropped.count
        forger.publish(f"{DONE}/robot1", StepDone("robot1", 0.1, {}, 0.2, run))
        assert barrier.dropped.count == dropped + 1  # its answers, from anyone, are refused
        assert not barrier.due(0.2)                # and no step stops for it
        wall.t += OUTLIVED_AFTER                   # its token lives on: a forger's
        barrier.publish(0.2)
        barrier.wait(0.2, stop)
        (said,) = tallies
        assert said.message.entries() == {("participant", "robot1", "outlived_process", True): 1}
        assert said.key == "simulator/refused/tally"
        token.close()
    finally:
        stop.set()
        source.close()
        barrier.close()


class _Process:
    def __init__(self):
        self.alive = True

    def running(self) -> bool:
        return self.alive


def test_the_runner_notes_each_member_whose_process_ended_once(tmp_path):
    path = tmp_path / "ended"
    assert read_ended(path) == frozenset()
    robot1, robot2 = _Process(), _Process()
    with EndedWatch(path, {"robot1": robot1.running, "robot2": robot2.running}) as watch:
        assert read_ended(path) == frozenset()
        robot2.alive = False
        wait_for(lambda: read_ended(path) == {"robot2"})
        watch.look()
    assert path.read_text() == "robot2\n"
    path.write_text("robot2\nrobot1")  # a line still being written is not read
    assert read_ended(path) == {"robot2"}
