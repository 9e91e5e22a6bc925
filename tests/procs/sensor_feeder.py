"""Publishes fresh odometry and sonar for the named robots at 10 Hz (a stand-in simulator).

argv: [--connect ENDPOINT] ROBOT… — with --connect, a client of that router (a robot's own
sensors on its own island), else a zero-configuration peer."""

import sys
import time

from mrta_zenoh import keys
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist

args = sys.argv[1:]
options = BusOptions()
if args[:1] == ["--connect"]:
    options = BusOptions(mode="client", connect=[args[1]])
    args = args[2:]
robots = args
with stop_on_signals() as stop, open_bus(options) as bus:
    bus.declare_token("@mrta/test/feeder")
    print("ready", flush=True)
    while not stop.is_set():
        now = time.time()
        for r in robots:
            bus.publish(keys.odom(r), Odometry(Header(r, now, 0), Pose2D(0.0, 0.0, 0.0), Twist(0.0, 0.0)))
            bus.publish(keys.sonar(r), PointCloud(Header(r, now, 0), (Point2D(1.0, 0.0),)))
        stop.wait(0.1)
