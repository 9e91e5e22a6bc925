"""Publishes as an ALLIANCE agent would: token, task broadcasts and motivation, at 5 Hz.

argv: ROBOT [TASK] — with a TASK the robot is busy with it; without, it is online and idle.
Every 2 s it also sends a wrong-type sample and a malformed payload on the broadcast key.
"""

import sys
import time

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Header, Twist
from mrta_agent.alliance.messages import InterRobotCommunication, Motivation

robot = sys.argv[1]
task = sys.argv[2] if len(sys.argv) > 2 else None
with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
    bus.declare_token(ALLIANCE.agent_token(robot))
    key = ALLIANCE.key(robot, "inter_robot_communication")
    print("ready", flush=True)
    k = 0
    while not stop.is_set():
        now = time.time()
        if k % 10 == 0:
            bus.publish(key, Twist(1.0, 2.0))  # wrong type on a monitored key
            bus.publish_raw(key, "application/msgpack;alliance_msgs/InterRobotCommunication",
                            b"\xc1")  # malformed payload
        if task:
            bus.publish(key, InterRobotCommunication(Header(robot, now, k), task, 60.0))
            bus.publish(ALLIANCE.key(robot, "motivation", task), Motivation(
                Header(robot, now, k), task, 1.0, k % 10 > 5, False, k % 7 == 0, True,
                float(k % 20), 15.0, True))
        k += 1
        stop.wait(0.2)
