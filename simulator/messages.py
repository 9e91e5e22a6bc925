"""Messages only the simulator publishes."""

from __future__ import annotations

from mrta_zenoh.messages import Header, Message, message


@message("mrta_msgs/Bumper")
class Bumper(Message):
    """Contact state of a simulated robot (RosAria's bumper_state, reduced to what a 2-D body has).

    `stalled`: the motors push but the robot does not move; `collisions`: contacts begun so far."""

    header: Header
    stalled: bool
    contact: bool
    collisions: int
