"""ping_msgs/Ping: what the `ping/announce` layer publishes."""

from mrta_zenoh.messages import Header, Message, message


@message("ping_msgs/Ping")
class Ping(Message):
    header: Header
    count: int
