import threading

from mrta_zenoh.clock import ManualClock, Rate, SimClock


def test_manual_clock_wakes_sleepers_when_advanced():
    clock = ManualClock(10.0)
    woke = threading.Event()
    t = threading.Thread(target=lambda: clock.sleep_until(12.0) and woke.set())
    t.start()
    clock.advance(1.0)
    assert not woke.wait(0.1)
    clock.advance(1.0)
    assert woke.wait(1.0)
    t.join()


def test_sleep_returns_false_when_stopped():
    stop = threading.Event()
    stop.set()
    assert ManualClock().sleep_until(5.0, stop) is False


def test_sim_clock_never_goes_backwards():
    c = SimClock()
    assert not c.started.is_set()
    c.on_clock(5.0)
    c.on_clock(4.0)
    assert c.now() == 5.0 and c.started.is_set()


def test_rate_keeps_period_and_resynchronises_after_a_jump():
    clock = ManualClock(0.0)
    rate = Rate(clock, 2.0)
    assert rate._next == 0.5
    clock.set(0.5)
    rate.sleep()
    assert rate._next == 1.0
    clock.set(10.0)  # fell far behind
    rate.sleep()
    assert rate._next == 10.5


class FakeWall:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def test_forged_clock_samples_are_rejected_and_counted():
    wall = FakeWall()
    c = SimClock(wall=wall)
    assert c.on_clock(1.0, "run-a")
    assert not c.on_clock(1e9, "run-a")        # a jump of a billion seconds
    assert not c.on_clock(50.0, "run-b")       # another source while run-a is alive
    assert c.now() == 1.0 and c.rejected == 2
    assert c.on_clock(1.02, "run-a") and c.now() == 1.02


def test_non_finite_clock_stamps_never_reach_the_clock():
    import math

    import msgpack
    import pytest

    from mrta_zenoh import codec
    for bad in (math.inf, math.nan, 1e400):
        with pytest.raises(codec.NonFinite):
            codec.decode("rosgraph_msgs/Clock", msgpack.packb({"stamp": bad, "source": "x"}))


def test_a_restarted_simulator_is_adopted_after_silence_or_token_loss():
    wall = FakeWall()
    c = SimClock(wall=wall)
    c.on_clock(300.0, "run-a")
    wall.t = 0.5
    assert not c.on_clock(0.02, "run-b")       # run-a spoke 0.5 s ago: not yet
    wall.t = 2.6                               # run-a silent for 2.6 s: the new run wins
    assert c.on_clock(0.04, "run-b") and c.now() == 0.04 and c.restarts == 1
    c.source_lost()                            # run-b's token gone: run-c at once
    assert c.on_clock(0.02, "run-c") and c.source == "run-c"


def test_stalled_reports_a_stopped_clock():
    wall = FakeWall()
    c = SimClock(wall=wall)
    assert not c.stalled(2.0)                  # not started: nothing to say
    c.on_clock(1.0, "a")
    wall.t = 1.9
    assert not c.stalled(2.0)
    wall.t = 2.1
    assert c.stalled(2.0)
