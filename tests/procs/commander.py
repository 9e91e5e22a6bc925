"""Drives one simulated robot over Zenoh and reports what it observed, as one JSON line.

argv: ROBOT LINEAR SECONDS — command LINEAR m/s for SECONDS of simulated time, then go silent
(the simulator's watchdog must stop the robot) and report poses, counts and the clock.
"""

import json
import sys
import threading

from mrta_zenoh import keys
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.clock import SimClock, follow_sim_clock
from mrta_simulator.node import bumper_key
from mrta_zenoh.messages import Odometry, PointCloud, Twist
from mrta_simulator.messages import Bumper

robot, linear, seconds = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
clock = SimClock()
truth: list = []
counts = {"sonar": 0, "odom": 0, "bumper": 0}
first_sonar: list = []
lock = threading.Lock()


def on_truth(s):
    with lock:
        truth.append((s.message.header.stamp, s.message.pose.x, s.message.pose.y))


def count(kind):
    def h(s):
        counts[kind] += 1
        if kind == "sonar" and not first_sonar:
            first_sonar.append([[p.x, p.y] for p in s.message.points])
    return h


with open_bus(BusOptions()) as bus, follow_sim_clock(bus, clock):
    bus.subscribe(keys.ground_truth(robot), on_truth, msg_type=Odometry)
    bus.subscribe(keys.sonar(robot), count("sonar"), msg_type=PointCloud)
    bus.subscribe(keys.odom(robot), count("odom"), msg_type=Odometry)
    bus.subscribe(bumper_key(robot), count("bumper"), msg_type=Bumper)
    print("ready", flush=True)
    clock.started.wait(30)
    while True:
        with lock:
            if truth:
                break
        clock.sleep_until(clock.now() + 0.1)
    t0 = clock.now()
    with lock:
        start = truth[-1]
    while clock.now() < t0 + seconds:
        bus.publish(keys.cmd_vel(robot), Twist(linear, 0.0))
        clock.sleep_until(clock.now() + 0.1)
    t_silent = clock.now()
    clock.sleep_until(t_silent + 3.0)  # watchdog (0.5 s) + braking
    with lock:
        end = truth[-1]
        at_silence = min(truth, key=lambda r: abs(r[0] - t_silent))
    print(json.dumps({"start": start, "at_silence": at_silence, "end": end,
                      "commanded_for": t_silent - t0, "counts": counts,
                      "first_sonar": first_sonar[0], "clock": clock.now()}), flush=True)
