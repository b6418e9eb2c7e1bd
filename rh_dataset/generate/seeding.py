"""Seeding: (dataset seed, purpose, key...) in, an independent `numpy.random.Generator` out.

Every random choice of the generator comes from `rng_for(seed, purpose, subject, split, frame, ...)`, so any frame
can be produced on its own (a resumed run, another worker, a Ray task) and comes out the same.

Keys are integers (subject, frame) or strings (split and protocol names). The strings that the shipped scene files
use keep the fixed codes they always had (`LEGACY_KEY_CODES`), so datasets made before are reproduced bit for bit;
any other string (a split name of a user's scene file) is hashed (BLAKE2b, 64 bits), so two names never share a
stream because their bytes happen to add up to the same sum, as they did before this version.
"""
from __future__ import annotations

import hashlib

import numpy as np

__all__ = ["rng_for", "key_word", "hashed_keys", "PURPOSES", "LEGACY_KEY_CODES", "KEY_HASH"]

PURPOSES = {"character": 1, "camera": 2, "light": 3, "pose": 4, "render": 5}

# The words these strings were given before keys were hashed: the split names by table, the protocol keys by the
# old rule sum(UTF-8 bytes) + 1000. Frozen: changing one changes every dataset made with it.
LEGACY_KEY_CODES = {"train": 1, "test": 2, "a": 1097, "b": 1098, "protocol_a": 2074, "protocol_b": 2075}

KEY_HASH = "blake2b-64"
"""Recorded in dataset.json for a protocol whose keys include a hashed string (`hashed_keys`): such a dataset made
before keys were hashed used other streams, and must not be resumed into."""


def key_word(key: int | str) -> int:
    """The SeedSequence entropy word of one key."""
    if isinstance(key, int):
        return key
    if key in LEGACY_KEY_CODES:
        return LEGACY_KEY_CODES[key]
    h = int.from_bytes(hashlib.blake2b(key.encode("utf-8"), digest_size=8, person=b"rh-seed-key").digest(), "little")
    # The top bit set keeps the word two 32-bit words long in SeedSequence's entropy, never confusable with a
    # small integer key or a legacy code.
    return h | (1 << 63)


def rng_for(seed: int, purpose: str, *keys: int | str) -> np.random.Generator:
    """An independent generator for one purpose and one (subject, split, frame) key."""
    words = [seed, PURPOSES[purpose], *(key_word(k) for k in keys)]
    return np.random.default_rng(np.random.SeedSequence(words))


def hashed_keys(spec) -> list[str]:
    """The split names of a protocol description that are hashed rather than given a legacy code."""
    return [s.name for s in spec.splits if s.name not in LEGACY_KEY_CODES]
