"""Random streams: one master seed per run, one independent stream per robot.

Every process derives its robot's stream itself from (master seed, robot id), the way
`numpy.random.SeedSequence.spawn` derives children: the robot id's CRC-32 is the spawn key. So
two robots never draw the same numbers, and a robot's numbers do not depend on which other
robots exist or in which order processes start.
"""

from __future__ import annotations

import zlib

import numpy as np


def robot_seed_sequence(seed: int, robot_id: str) -> np.random.SeedSequence:
    return np.random.SeedSequence(entropy=seed, spawn_key=(zlib.crc32(robot_id.encode()),))


def robot_rng(seed: int, robot_id: str) -> np.random.Generator:
    return np.random.default_rng(robot_seed_sequence(seed, robot_id))
