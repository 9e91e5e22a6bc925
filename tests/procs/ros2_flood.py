"""A hostile ROS 2 publisher for the bridge's size cap (tests/test_ros2_bridge_limits.py):

    ros2_flood.py ROBOT BIG N [SMALL]   wait until the bridge of ROBOT subscribes to its sonar,
                                        put N sensor_msgs/PointCloud samples of BIG points on
                                        /ROBOT/sonar (twice a second), then SMALL-point ones until
                                        stopped; prints {"big": N} once the big ones are out

The CDR is built with numpy (a million points through rosbags' objects would take seconds)."""

import json
import struct
import sys
import time

import numpy as np

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.ros2.attachment import Stamper
from mrta_zenoh.ros2.names import topic_key
from mrta_zenoh.ros2.types import SONAR_TYPES, Ros2Types


def cloud(n: int, stamp: int) -> bytes:
    """sensor_msgs/PointCloud, little-endian CDR: header (stamp, frame_id "s"), n Point32 on a
    2 m circle, no channels."""
    head = b"\x00\x01\x00\x00" + struct.pack("<iI", stamp, 0) + struct.pack("<I", 2) + b"s\x00"
    head += b"\x00" * (-len(head[4:]) % 4)
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    pts = np.zeros((n, 3), dtype="<f4")
    pts[:, 0], pts[:, 1] = 2 * np.cos(a), 2 * np.sin(a)
    return head + struct.pack("<I", n) + pts.tobytes() + struct.pack("<I", 0)


def main(robot: str, big: str, n: str, small: str = "16") -> None:
    kind = SONAR_TYPES["pointcloud"]
    key = topic_key(0, f"/{robot}/sonar", kind, Ros2Types("jazzy").hash(kind))
    stamper = Stamper()
    with open_bus(BusOptions()) as bus:
        pub = bus.declare_attached_publisher(key, lossy=False)
        deadline = time.monotonic() + 30
        while getattr(pub._native.matching_status, "matching", None) is not True:
            if time.monotonic() > deadline:
                raise SystemExit(f"no subscriber on {key}")
            time.sleep(0.02)
        payload = cloud(int(big), 1)
        for i in range(int(n)):
            pub.put(payload, stamper.next(time.time_ns()))
            time.sleep(0.5)
        print(json.dumps({"big": int(n), "bytes": len(payload)}), flush=True)
        i = 0
        while True:
            i += 1
            pub.put(cloud(int(small), 100 + i), stamper.next(time.time_ns()))
            time.sleep(0.1)


if __name__ == "__main__":
    main(*sys.argv[1:])
