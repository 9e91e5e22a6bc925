"""Random streams: one master seed per run, one independent stream per robot.

Every process derives its robot's stream itself from (master seed, robot id), the way
`numpy.random.SeedSequence.spawn` derives children: the robot id's CRC-32 is the spawn key. So
two robots never draw the same numbers, and a robot's numbers do not depend on which other
robots exist or in which order processes start.

A robot's stream is created on its first draw (`LazyGenerator`): numpy costs an agent process
about 14 MB and 35 ms to import, and most plugins never draw (issue #27: an agent loads only
what it uses). The numbers are the same as an eager generator's. A plugin that draws says so
(`Plugin.draws`), and its stream is made at setup (`prepare`), before the run's first step.
"""

from __future__ import annotations

import zlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np


def robot_seed_sequence(seed: int, robot_id: str) -> "np.random.SeedSequence":
    import numpy as np

    return np.random.SeedSequence(entropy=seed, spawn_key=(zlib.crc32(robot_id.encode()),))


class LazyGenerator:
    """A `numpy.random.Generator` made on first use: every attribute is the generator's."""

    def __init__(self, seed: int, robot_id: str) -> None:
        self._seed, self._robot_id = seed, robot_id
        self._generator: "np.random.Generator | None" = None

    @property
    def generator(self) -> "np.random.Generator":
        if self._generator is None:
            import numpy as np

            self._generator = np.random.default_rng(robot_seed_sequence(self._seed,
                                                                        self._robot_id))
        return self._generator

    def __getattr__(self, name: str) -> Any:
        return getattr(self.generator, name)

    def __repr__(self) -> str:
        state = "drawn from" if self._generator is not None else "not yet drawn from"
        return f"LazyGenerator(seed={self._seed}, robot_id={self._robot_id!r}, {state})"


def robot_rng(seed: int, robot_id: str) -> "np.random.Generator":
    """Robot `robot_id`'s stream of run `seed` (created when first drawn from)."""
    return LazyGenerator(seed, robot_id)  # type: ignore[return-value]


def prepare(rng: Any) -> None:
    """Make a lazy stream now (a generator that is not lazy is left as it is): the import and
    the seeding then happen at setup, not at the first draw inside a tick."""
    if isinstance(rng, LazyGenerator):
        rng.generator
