"""Random numbers of a run: one master seed, and every draw named by a path below it.

The one derivation (docs/architecture.md, "Random streams"): whatever draws — the simulator's
world, a robot's plugins, a fault — names what it draws for by a path of names, and its numbers
come from (run seed, path) alone. Two parts of a run never share numbers, and what one draws
does not depend on which other parts exist or in which order processes start.

Two ways to draw along a path, for two needs:

* `stream(seed, *path)`: a sequence of draws (numpy's `Generator`), from
  `SeedSequence(entropy=seed, spawn_key=(crc32(name) for name in path))` — how
  `SeedSequence.spawn` derives children, with each name's CRC-32 as its spawn key. The
  simulator's world draws from the root (path `()`, which is `numpy.random.default_rng(seed)`);
  robot R's plugins from `(R,)`.
* `uniform(seed, *path)`: one number in [0, 1) for one event, from a BLAKE2b hash of the seed
  and the path. Per-message fault draws (loss and latency: path `("loss", receiver, key,
  sequence number)`) use it rather than a stream: a stream's k-th number would go to whichever
  message happened to arrive k-th, so the draws would follow the network's order; a hash of the
  message's own name does not, and a lockstep run replays exactly.

A robot's stream is created on its first draw (`LazyGenerator`): numpy costs an agent process
about 14 MB and 35 ms to import, and most plugins never draw (an agent loads only what it uses).
The numbers are the same as an eager generator's. A plugin that draws says so (`Plugin.draws`),
and its stream is made at setup (`prepare`), before the run's first step.

How the seed reaches each process: `$MRTA_SEED` (SEED_ENV), set by the runner for every process
it starts (the mission runner from `--seed`; a launch file from its `seed` argument) and read by
every verb's `--seed`, so no process of a run can be left on another seed by a launch file that
forgot to pass it.
"""

from __future__ import annotations

import zlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import numpy as np

SEED_ENV = "MRTA_SEED"  # the run's master seed, for every process of the run (module docstring)


def seed_sequence(seed: int, *path: str) -> "np.random.SeedSequence":
    """The SeedSequence of `path` below run `seed` (module docstring)."""
    import numpy as np

    return np.random.SeedSequence(entropy=seed,
                                  spawn_key=tuple(zlib.crc32(name.encode()) for name in path))


def generator(seed: int, *path: str) -> "np.random.Generator":
    """The stream of `path` below run `seed`, made now (the simulator's, which draws at once)."""
    import numpy as np

    return np.random.default_rng(seed_sequence(seed, *path))


class LazyGenerator:
    """A `numpy.random.Generator` made on first use: every attribute is the generator's."""

    def __init__(self, seed: int, *path: str) -> None:
        self._seed, self._path = seed, path
        self._generator: "np.random.Generator | None" = None

    @property
    def generator(self) -> "np.random.Generator":
        if self._generator is None:
            self._generator = generator(self._seed, *self._path)
        return self._generator

    def __getattr__(self, name: str) -> Any:
        return getattr(self.generator, name)

    def __repr__(self) -> str:
        state = "drawn from" if self._generator is not None else "not yet drawn from"
        return f"LazyGenerator(seed={self._seed}, path={self._path!r}, {state})"


def stream(seed: int, *path: str) -> "np.random.Generator":
    """The stream of `path` below run `seed`, made when first drawn from."""
    return LazyGenerator(seed, *path)  # type: ignore[return-value]


def robot_rng(seed: int, robot_id: str) -> "np.random.Generator":
    """Robot `robot_id`'s stream of run `seed`: path `(robot_id,)` (made when first drawn from)."""
    return stream(seed, robot_id)


def uniform(seed: int, *path: object) -> float:
    """One number in [0, 1) for the event `path` of run `seed`: the same seed and path, the same
    number, in any process and in any order. BLAKE2b without hashlib: importing hashlib loads
    OpenSSL (≈ 3 MB of every agent's RSS), as lockstep's digests avoid too."""
    from _blake2 import blake2b

    digest = blake2b("\0".join(map(str, (seed, *path))).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big") / 2.0 ** 64


def prepare(rng: Any) -> None:
    """Make a lazy stream now (a generator that is not lazy is left as it is): the import and
    the seeding then happen at setup, not at the first draw inside a tick."""
    if isinstance(rng, LazyGenerator):
        rng.generator
