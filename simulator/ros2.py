"""The simulator's ROS 2 stand-in (`mrta sim … --ros2 robot2`): a simulated Pioneer served as a
ROS 2 robot over rmw_zenoh, as a robot's own driver would serve it — a node
`/<robot>/pioneer_driver` taking geometry_msgs/Twist on `cmd_vel` and publishing
nav_msgs/Odometry on `odom` and its sonar on `sonar` (PointCloud like RosAria, or PointCloud2 /
LaserScan). The robot's data then never appear on our keys: our side reaches it only through
`mrta ros2 bridge`, exactly as with a real robot, so a whole mission can run with some robots
on the ROS 2 side.

A ROS 2 robot cannot take part in lockstep (its driver and the bridge run on their own time),
so `--ros2` and `--lockstep` exclude each other (simulator/api.py says so to the user).
"""

from __future__ import annotations

import logging
from typing import Callable

from mrta_zenoh.messages import Odometry, PointCloud
from mrta_zenoh.ros2.names import COMMANDS, SENSOR_DATA
from mrta_zenoh.ros2.node import Ros2Node
from mrta_zenoh.ros2.types import ODOMETRY, SONAR_TYPES, TWIST, Ros2Types

log = logging.getLogger("mrta.sim")
DRIVER_NODE = "pioneer_driver"


class Ros2Driver:
    def __init__(self, bus, robots: list[str], on_command: Callable[[str, float, float], None],
                 *, domain: int = 0, distro: str = "jazzy", sonar_type: str = "pointcloud"):
        self.types = Ros2Types(distro)
        self.sonar_type = sonar_type
        self.nodes: dict[str, Ros2Node] = {}
        self._pubs: dict[str, tuple] = {}
        for rid in robots:
            node = Ros2Node(bus, self.types, name=DRIVER_NODE, namespace="/" + rid, domain=domain)

            def on_cmd(msg, att, rid=rid) -> None:
                twist = self.types.twist_from_ros(msg)
                on_command(rid, twist.linear, twist.angular)

            node.subscription("cmd_vel", TWIST, COMMANDS, on_cmd)
            self._pubs[rid] = (node.publisher("odom", ODOMETRY, SENSOR_DATA),
                               node.publisher("sonar", SONAR_TYPES[sonar_type], SENSOR_DATA))
            self.nodes[rid] = node
            log.info("%s is served as a ROS 2 robot: %s/%s (cmd_vel, odom, sonar as %s)", rid,
                     node.namespace, DRIVER_NODE, sonar_type)

    def publish(self, rid: str, odom: Odometry, sonar: PointCloud) -> None:
        odom_pub, sonar_pub = self._pubs[rid]
        odom_pub.publish(self.types.odometry_to_ros(odom))
        sonar_pub.publish(self.types.sonar_to_ros(sonar, self.sonar_type))

    def close(self) -> None:
        for node in self.nodes.values():
            node.close()
        self.nodes.clear()
