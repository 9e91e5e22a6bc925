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
