"""An independent ROS 2 peer: zenoh-ros2-sdk (ROBOTIS), speaking rmw_zenoh from plain Python,
with vendored message files (tests/harness/ros2_msgs.py) so it never downloads anything.

    sdk_peer.py MSGS_DIR ROUTER_PORT sub-twist TOPIC          print each Twist as a JSON line
    sdk_peer.py MSGS_DIR ROUTER_PORT pub-odom TOPIC N         publish N Odometry at 20 Hz
    sdk_peer.py MSGS_DIR ROUTER_PORT topic-list [EXPECTED…] print the topics it discovers
    sdk_peer.py MSGS_DIR ROUTER_PORT driver NAMESPACE         a robot's driver node: publishes
                                                              odom in NAMESPACE at 5 Hz, forever

Loopback only: the router is on 127.0.0.1, the SDK's own listener too, multicast scouting off.
"""

import json
import math
import os
import sys
import time

os.environ["ZENOH_CONFIG_OVERRIDE"] = (
    'listen/endpoints=["tcp/127.0.0.1:0"];scouting/multicast/enabled=false')

from zenoh_ros2_sdk import ROS2Publisher, ROS2Subscriber, ZenohSession  # noqa: E402
from zenoh_ros2_sdk.discovery import get_topic_names_and_types  # noqa: E402
from zenoh_ros2_sdk.message_registry import get_registry  # noqa: E402


def odometry(t, i: int) -> dict:
    """The i-th Odometry's fields: x = 0.5·i, y = -1, θ = 0.1·i, stamp 100 + i + 0.5 s."""
    import numpy as np

    theta = 0.1 * i
    pose = t["geometry_msgs/msg/Pose"](
        t["geometry_msgs/msg/Point"](0.5 * i, -1.0, 0.0),
        t["geometry_msgs/msg/Quaternion"](0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2)))
    twist = t["geometry_msgs/msg/Twist"](t["geometry_msgs/msg/Vector3"](0.2, 0.0, 0.0),
                                         t["geometry_msgs/msg/Vector3"](0.0, 0.0, 0.1))
    return dict(
        header=t["std_msgs/msg/Header"](t["builtin_interfaces/msg/Time"](100 + i, 500_000_000),
                                        "odom"),
        child_frame_id="base_link",
        pose=t["geometry_msgs/msg/PoseWithCovariance"](pose, np.zeros(36)),
        twist=t["geometry_msgs/msg/TwistWithCovariance"](twist, np.zeros(36)))


def main(msgs: str, port: str, mode: str, *args: str) -> None:
    get_registry(msgs)  # the vendored files, before anything asks for a type
    port = int(port)
    if mode == "sub-twist":
        def on_twist(msg):
            print(json.dumps({"linear": msg.linear.x, "angular": msg.angular.z}), flush=True)

        ROS2Subscriber(args[0], "geometry_msgs/msg/Twist", on_twist, node_name="sdk_listener",
                       router_port=port)
        print(json.dumps({"ready": True}), flush=True)
        while True:
            time.sleep(1)
    elif mode == "pub-odom":
        pub = ROS2Publisher(args[0], "nav_msgs/msg/Odometry", node_name="sdk_driver",
                            router_port=port)
        t = ZenohSession.get_instance().store.types
        print(json.dumps({"ready": True}), flush=True)
        time.sleep(1.0)  # let our subscription's declaration reach it
        for i in range(int(args[1])):
            pub.publish(**odometry(t, i))
            time.sleep(0.05)
        print(json.dumps({"published": int(args[1])}), flush=True)
        time.sleep(0.5)
    elif mode == "driver":
        pub = ROS2Publisher(args[0].rstrip("/") + "/odom", "nav_msgs/msg/Odometry",
                            node_name="sdk_driver",
                            namespace=args[0], router_port=port)
        t = ZenohSession.get_instance().store.types
        print(json.dumps({"ready": True}), flush=True)
        i = 0
        while True:
            pub.publish(**odometry(t, i))
            i += 1
            time.sleep(0.2)
    elif mode == "topic-list":
        # as a user re-runs `ros2 topic list` while the session is still connecting: ask again
        # until every EXPECTED topic is listed, for at most 30 s
        deadline = time.monotonic() + 30
        while True:
            topics = dict(get_topic_names_and_types(router_port=port, timeout=2.0))
            if all(t in topics for t in args) or time.monotonic() > deadline:
                break
        print(json.dumps({"topics": topics}), flush=True)
    else:
        raise SystemExit(f"unknown mode {mode!r}")


if __name__ == "__main__":
    main(*sys.argv[1:])
