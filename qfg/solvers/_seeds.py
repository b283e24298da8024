"""Random streams: one per (view, purpose), so that adding a view draws exactly what a batch solve
of all views draws for it.
"""

from __future__ import annotations

import numpy as np

from .._validate import as_seed_sequence

#: spawn-key purposes
STREAM_CAMERAS, STREAM_RESAMPLE, STREAM_LANDMARKS, STREAM_POSTERIOR, STREAM_RETRY = 0, 1, 3, 4, 5


STREAM_MOVE = 6


def root_seed(seed) -> np.random.SeedSequence:
    """A SeedSequence by the project's seed rule (:func:`qfg._validate.as_seed_sequence`)."""
    return as_seed_sequence(seed)


def child_seed(root: np.random.SeedSequence, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(root.entropy, spawn_key=tuple(root.spawn_key) + tuple(key))


def stream(root: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """The generator of stream ``key`` under ``root`` (e.g. ``(view, STREAM_CAMERAS)``)."""
    return np.random.default_rng(child_seed(root, *key))
