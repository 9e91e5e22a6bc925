"""Our side of the ROS 2 interop tests, as a separate process on the test's rendezvous.

    ros2_probe.py cmd ROBOT N              wait for the bridge of ROBOT, then publish up to N
                                           Twist (linear 0.1·i, angular -0.2) on ROBOT/cmd_vel
                                           at 10 Hz (the test stops it once it has seen enough)
    ros2_probe.py attachments KEYEXPR      print every sample's attachment on a ROS 2 key
    ros2_probe.py unattached KEY N         put N CDR Odometry samples on KEY with no attachment,
                                           then N with a 77-byte one (the early-Jazzy layout)

With $PROBE_CONNECT set, it is a client of that endpoint (a robot's router) instead.
"""

import json
import os
import sys
import threading
import time

import zenoh

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.keys import ROS2_BRIDGE_TOKEN
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_zenoh.ros2.types import Ros2Types


def main(mode: str, *args: str) -> None:
    connect = os.environ.get("PROBE_CONNECT")
    with open_bus(BusOptions(mode="client", connect=[connect]) if connect else BusOptions()) as bus:
        if mode == "cmd":
            robot, n = args[0], int(args[1])
            up = threading.Event()
            bus.watch_liveliness(f"{ROS2_BRIDGE_TOKEN}/{robot}", lambda k, alive: alive and up.set())
            if not up.wait(30):
                raise SystemExit("no bridge")
            for i in range(n):
                bus.publish(f"{robot}/cmd_vel", Twist(0.1 * i, -0.2))
                time.sleep(0.1)
            print(json.dumps({"sent": n}), flush=True)
            time.sleep(0.5)
        elif mode == "attachments":
            def on_sample(key, payload, attachment):
                print(json.dumps({"key": key, "payload": payload.hex(),
                                  "attachment": attachment.hex() if attachment else None}),
                      flush=True)

            bus.subscribe_attached(args[0], on_sample)
            print(json.dumps({"ready": True}), flush=True)
            threading.Event().wait()
        elif mode == "unattached":
            key, n = args[0], int(args[1])
            types = Ros2Types("jazzy")
            cdr = types.serialize(types.odometry_to_ros(
                Odometry(Header("x", 1.0, 0), Pose2D(9.0, 9.0, 0.0), Twist(0.0, 0.0))),
                "nav_msgs/msg/Odometry")
            # sent once Zenoh reports the bridge's subscription as matching, not after a pause
            pub = bus.session.declare_publisher(
                key, congestion_control=zenoh.CongestionControl.BLOCK)
            deadline = time.monotonic() + 30
            while getattr(pub.matching_status, "matching", pub.matching_status) is not True:
                if time.monotonic() > deadline:
                    raise SystemExit(f"no subscriber on {key}")
                time.sleep(0.02)
            for i in range(n):
                pub.put(cdr)
            for i in range(n):
                pub.put(cdr, attachment=b"\x00" * 77)
            time.sleep(0.5)
            pub.undeclare()
            print(json.dumps({"sent": 2 * n}), flush=True)
        else:
            raise SystemExit(f"unknown mode {mode!r}")


if __name__ == "__main__":
    main(*sys.argv[1:])
