"""A robot's own ROS 2 driver as the robot would run it next to rmw_zenohd: a peer that connects
to the robot's router and that nobody can reach directly (it listens nowhere and gossip is off,
as a robot node listening on the robot's localhost is out of reach from another host). It is
the simulator's stand-in (mrta_simulator.ros2.Ros2Driver): Twist in on /ROBOT/cmd_vel, Odometry and
PointCloud out on /ROBOT/odom and /ROBOT/sonar at 10 Hz.

    ros2_robot_node.py ROUTER_PORT ROBOT CONFIG_DIR
        prints {"cmd": [linear, angular]} per command received
"""

import json
import sys
import threading
from pathlib import Path

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
from mrta_simulator.ros2 import Ros2Driver


def main(port: str, robot: str, config_dir: str) -> None:
    cfg = Path(config_dir) / "robot_node.json5"
    cfg.write_text(json.dumps({"listen": {"endpoints": []},
                               "scouting": {"gossip": {"enabled": False}}}))
    opts = BusOptions(mode="peer", connect=[f"tcp/127.0.0.1:{int(port)}"], zenoh_config=cfg)

    def on_command(rid: str, linear: float, angular: float) -> None:
        print(json.dumps({"cmd": [linear, angular]}), flush=True)

    stop = threading.Event()
    with open_bus(opts) as bus:
        driver = Ros2Driver(bus, [robot], on_command)
        try:
            print(json.dumps({"ready": True}), flush=True)
            i = 0
            while not stop.wait(0.1):
                i += 1
                driver.publish(robot, Odometry(Header(f"{robot}/odom", 0.1 * i, i),
                                               Pose2D(0.01 * i, 2.0, 0.0), Twist(0.1, 0.0)),
                               PointCloud(Header(f"{robot}/sonar", 0.1 * i, i),
                                          (Point2D(1.0, 0.0),)))
        finally:
            driver.close()


if __name__ == "__main__":
    main(*sys.argv[1:])
