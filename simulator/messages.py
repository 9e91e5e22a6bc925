"""Messages only the simulator publishes."""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message


@message("mrta_msgs/Bumper")
class Bumper(Message):
    """Contact state of a simulated robot (RosAria's bumper_state, reduced to what a 2-D body has).

    `stalled`: the motors push but the robot does not move; `collisions`: contacts begun so far."""

    header: Header
    stalled: bool
    contact: bool
    collisions: int


@message("mrta_msgs/Segment")
class Segment(Message):
    x1: Finite
    y1: Finite
    x2: Finite
    y2: Finite


@message("mrta_msgs/World")
class World(Message):
    """The simulated world's walls (metres), published on `world` now and then, so that any
    viewer can draw the scene without reading the world file."""

    header: Header
    name: str
    walls: tuple[Segment, ...]
