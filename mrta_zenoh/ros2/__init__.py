"""ROS 2 over rmw_zenoh, with no ROS 2 installation (docs/ros2.md).

ROS 2's Zenoh middleware, rmw_zenoh, puts every topic on Zenoh: a key
`<domain>/<topic>/<pkg>::msg::dds_::<Name>_/RIHS01_<hash>`, a CDR payload, a 33-byte attachment,
and liveliness tokens under `@ros2_lv/<domain>/…` that make up the ROS graph. Since we are on
Zenoh already, speaking it is a matter of names, bytes and tokens:

    names.py       key expressions, DDS type names, liveliness tokens, QoS strings (pure)
    attachment.py  the per-sample attachment: sequence number, timestamp, publisher GID (pure)
    types.py       CDR and RIHS01 type hashes through `rosbags`, and our messages ↔ ROS 2's
    node.py        a ROS 2 node on a ZenohBus: its tokens, publishers and subscriptions
    graph.py       the ROS 2 graph read from liveliness tokens (`mrta ros2 graph`, supervisor)
    bridge.py      `mrta ros2 bridge`: a robot's topics ↔ our keys

The core knows no architecture: an architecture's own messages reach ROS 2 tools through the
`mrta.ros2.mirrors` entry points (ALLIANCE registers InterRobotCommunication and Motivation).
"""
