"""The simulator's role in a secured fleet (`mrta secure init`, docs/security.md).

Registered under the `mrta.secure.roles` entry points, so the keys the simulator publishes and
the token it holds are stated here, beside the code that uses them, and the core's access-control
generator never has to know a simulator's topics. A key the simulator starts publishing must be
added here, or a secured router will silently drop it.
"""

from __future__ import annotations

from mrta_zenoh import keys

from .node import WORLD_KEY, bumper_key


def role() -> dict[str, list[str]]:
    """Publish: the clock, every robot's sensor streams and the world's walls (for viewers);
    tokens: the clock source's. Subscribing is left to the default (everything): the simulator
    listens to every robot's `cmd_vel` and tokens, and to lockstep."""
    any_robot = "*"
    return {
        "publish": [keys.CLOCK, keys.sonar(any_robot), keys.odom(any_robot),
                    keys.ground_truth(any_robot), bumper_key(any_robot), WORLD_KEY],
        "tokens": [f"{keys.CLOCK_SOURCE_TOKEN}/**"],
    }
