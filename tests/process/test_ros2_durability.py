"""TRANSIENT_LOCAL as rmw_zenoh does it (zenoh-ext's AdvancedPublisher / AdvancedSubscriber):
a late subscription gets the publisher's last `depth` samples, with their attachments; a
volatile one gets none. Two real sessions in this process, on a free loopback port."""

import threading
import time

import pytest

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.ros2.names import KEEP_LAST, RELIABLE, TRANSIENT_LOCAL, Qos
from mrta_zenoh.ros2.node import Ros2Node
from mrta_zenoh.ros2.types import Ros2Types
from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess

LATCHED = Qos(RELIABLE, TRANSIENT_LOCAL, KEEP_LAST, 2)
TWIST = "geometry_msgs/msg/Twist"


def _wait(predicate, timeout=30.0):
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


@pytest.mark.slow
def test_a_late_transient_local_subscription_gets_the_last_depth_samples():
    types = Ros2Types("jazzy")
    end = f"tcp/127.0.0.1:{free_port()}"
    with open_bus(BusOptions(listen=[end])) as a, open_bus(BusOptions(connect=[end])) as b:
        talker = Ros2Node(a, types, name="talker")
        listener = Ros2Node(b, types, name="listener")
        try:
            pub = talker.publisher("/map_like", TWIST, LATCHED)
            for i in range(1, 4):
                pub.publish(types.twist_to_ros(_twist(i)))
            got, lock = [], threading.Lock()

            def on(msg, att):
                with lock:
                    got.append((msg.linear.x, att.sequence, att.gid))

            listener.subscription("/map_like", TWIST, LATCHED, on)
            assert _wait(lambda: len(got) >= 2), got
            with lock:
                assert sorted(g[:2] for g in got) == [(2.0, 2), (3.0, 3)]  # depth 2: not 1
                assert all(g[2] == pub.gid for g in got)
            # and what comes after arrives live
            pub.publish(types.twist_to_ros(_twist(4)))
            assert _wait(lambda: any(g[0] == 4.0 for g in got)), got
        finally:
            listener.close()
            talker.close()


def _twist(x):
    from mrta_zenoh.messages import Twist

    return Twist(float(x), 0.0)
