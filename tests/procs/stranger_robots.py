"""Robots outside the application: each holds an ALLIANCE agent token and claims every task
at 5 Hz (expected duration 1000 s, so a robot that believes them waits for ages).

argv: TASKS ROBOT… — TASKS comma-separated."""

import sys
import time

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Header

tasks = sys.argv[1].split(",")
robots = sys.argv[2:]
with stop_on_signals() as stop, open_bus(BusOptions()) as bus:
    held = [bus.declare_token(ALLIANCE.agent_token(r)) for r in robots]
    print("ready", flush=True)
    seq = 0
    while not stop.is_set():
        seq += 1
        for r in robots:
            for t in tasks:
                bus.publish(ALLIANCE.key(r, "inter_robot_communication"),
                            InterRobotCommunication(Header(r, time.time(), seq), t, 1000.0))
        stop.wait(0.2)
