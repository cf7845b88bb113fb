"""Independent, reproducible random streams derived from the config's one seed."""

import zlib

import numpy as np


def rng_for(seed: int, *keys) -> np.random.Generator:
    """A generator for (seed, keys...): the same keys give the same stream on every run and machine.

    String keys enter through CRC32 (Python's hash() is salted per process, so it would not repeat).
    """
    words = [seed] + [zlib.crc32(k.encode()) if isinstance(k, str) else int(k) for k in keys]
    return np.random.default_rng(np.random.SeedSequence(words))
