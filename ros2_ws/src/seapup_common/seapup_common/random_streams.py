"""Independent, reproducible random streams, one per component.

One ``numpy.random.Generator`` shared by several components couples them:
drawing one more number in one (a sensor profile with more noise, a position
fix that drops out) changes every later draw of the others (the current's
realisation, say). :class:`RandomStreams` gives each named component its own
generator, derived from the run's seed and the component's name only, so a
component's draws depend on the seed and on nothing else the run does -- not
on which other components exist, in which order they were created, or how
many numbers they draw.

The streams come from ``numpy.random.SeedSequence(seed, spawn_key=(k,))``
with ``k`` a stable 32-bit hash (CRC-32) of the name: the children of one
seed that ``SeedSequence.spawn`` would give, addressed by name instead of by
creation order.
"""
from __future__ import annotations

import zlib

import numpy as np

__all__ = ["RandomStreams"]


class RandomStreams:
    """Named random generators derived from one seed.

    Parameters
    ----------
    seed : int
        The run's seed, >= 0.

    Examples
    --------
    >>> a, b = RandomStreams(7), RandomStreams(7)
    >>> _ = a.generator("sensors.velocity").standard_normal(1000)
    >>> float(a.generator("current").random()) == float(b.generator("current").random())
    True
    """

    def __init__(self, seed: int):
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        self.seed = int(seed)

    @staticmethod
    def key(name: str) -> int:
        """The stable spawn key of a component name."""
        if not name:
            raise ValueError("a random stream needs a non-empty name")
        return zlib.crc32(name.encode())

    def sequence(self, name: str) -> np.random.SeedSequence:
        """The ``SeedSequence`` of component ``name``."""
        return np.random.SeedSequence(self.seed, spawn_key=(self.key(name),))

    def generator(self, name: str) -> np.random.Generator:
        """A new generator for component ``name`` (the same draws every time it is asked for)."""
        return np.random.Generator(np.random.PCG64(self.sequence(name)))
