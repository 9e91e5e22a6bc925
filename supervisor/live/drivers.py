"""Robots driven through ROS 2: the rules that make one offline when its driver is gone.

A robot is driven through ROS 2 while a bridge holds `@mrta/ros2_bridge/<robot>`: from the
first ROS 2 node seen in its namespace on, it is online only while such a node lives
(`driver_lost` otherwise). The rule goes with the bridge: a node declared in the namespace of a
robot nobody bridges (a forgery, a stray tool) changes nothing, and when the bridge goes its
`driver_lost` goes with it. A robot so driven whose bridge goes while its driver lives is
offline with `bridge_lost` (its agent's commands reach nothing) until a bridge comes back or its
ROS 2 nodes go too. The graph itself (mrta_zenoh.ros2.graph) is bounded and linear; a token
that does not parse raises `ros2_invalid_token`, a full graph `ros2_graph_full`, while they
last."""

from __future__ import annotations

from mrta_zenoh.ros2.graph import Ros2Graph

from .alarms import Alarms
from .entities import RobotInfo


class Ros2Drivers:
    def __init__(self, graph: Ros2Graph, alarms: Alarms):
        self.graph, self.alarms = graph, alarms

    def on_token(self, key: str, alive: bool, now: float) -> str | None:
        """A token of the ROS 2 graph (`@ros2_lv/<domain>/…`), taken in O(1): the robot whose
        nodes changed (None: none did). Call outside the supervisor's lock: the graph has its
        own."""
        return self.graph.on_token(key, alive).robot

    def graph_alarms(self, now: float) -> None:
        g = self.graph
        self.alarms.set("ros2_invalid_token", g.key_expr, g.invalid_live > 0, now)
        self.alarms.set("ros2_graph_full", g.key_expr, g.refused_live > 0, now)

    @staticmethod
    def on_bridge(r: RobotInfo, key: str, alive: bool) -> None:
        """`@mrta/ros2_bridge/<robot>`: a bridge drives that robot through ROS 2 (or stopped)."""
        (r.bridges.add if alive else r.bridges.discard)(key)

    def reassess(self, r: RobotInfo, now: float) -> None:
        """The robot's driver flags and alarms after its nodes or bridges changed."""
        r.ros2_driver = self.graph.has_nodes(r.id)
        if not r.bridges:  # nobody bridges it: ROS 2 nodes in its namespace say nothing…
            self.alarms.clear("driver_lost", r.id, now)
            if r.ever_ros2 and r.ros2_driver:  # …unless a bridge drove them and died
                self.alarms.raise_("bridge_lost", r.id, now)
            else:
                r.ever_ros2 = False
                self.alarms.clear("bridge_lost", r.id, now)
        else:
            self.alarms.clear("bridge_lost", r.id, now)
            r.ever_ros2 = r.ever_ros2 or r.ros2_driver
            self.alarms.set("driver_lost", r.id, r.ever_ros2 and not r.ros2_driver, now)

    @staticmethod
    def cut_off(r: RobotInfo) -> bool:
        """Offline whatever its tokens say: its ROS 2 driver or its bridge is gone."""
        return r.ever_ros2 and not (r.ros2_driver and r.bridges)
