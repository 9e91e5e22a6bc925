"""The simulator's role in a secured fleet (`mrta secure init`, docs/security.md).

Registered under the `mrta.secure.roles` entry points, so the keys the simulator publishes and
the tokens it holds are stated here, beside the code that uses them, and the core's access-control
generator never has to know a simulator's topics. A key the simulator starts publishing must be
added here, or a secured router will silently drop it (tests/process/test_secure_fleet.py runs the
lockstep mission through a secured router and compares it with an open one).
"""

from __future__ import annotations

from mrta_zenoh import keys
from mrta_zenoh.lockstep.protocol import BARRIER, STATUS, STEP
from mrta_zenoh.refusal_tally import refused_key

from .node import WORLD_KEY, bumper_key

SIMULATOR_ROLE = "simulator"  # this role's name under mrta.secure.roles (pyproject.toml)


def role() -> dict[str, list[str]]:
    """Publish: the clock, every robot's sensor streams, the world's walls (for viewers),
    lockstep's steps and status, and what its barrier refused (a member's participant token
    outliving its process: mrta_zenoh/lockstep/ended.py); tokens: the clock source's and the lockstep barrier's.
    Subscribing is left to the default (everything): the simulator listens to every robot's
    `cmd_vel` and tokens, and to lockstep."""
    any_robot = "*"
    return {
        "publish": [keys.CLOCK, keys.sonar(any_robot), keys.odom(any_robot),
                    keys.ground_truth(any_robot), bumper_key(any_robot), WORLD_KEY,
                    STEP, STATUS, refused_key(SIMULATOR_ROLE)],
        "tokens": [f"{keys.CLOCK_SOURCE_TOKEN}/**", f"{BARRIER}/**"],
    }
