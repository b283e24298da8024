"""Random streams: one per (view, purpose), so that adding a view draws exactly what a batch solve
of all views draws for it.
"""

from __future__ import annotations

import numpy as np

from ..._validate import as_seed_sequence

#: spawn-key purposes
STREAM_CAMERAS, STREAM_RESAMPLE, STREAM_LANDMARKS, STREAM_POSTERIOR, STREAM_RETRY = 0, 1, 3, 4, 5


STREAM_MOVE = 6
#: the rejuvenation moves (:func:`.moves._rejuvenate`)
STREAM_REJUVENATE = 7


def root_seed(seed) -> np.random.SeedSequence:
    """A SeedSequence by the project's seed rule (:func:`qfg._validate.as_seed_sequence`)."""
    return as_seed_sequence(seed)


def child_seed(root: np.random.SeedSequence, *key: int) -> np.random.SeedSequence:
    return np.random.SeedSequence(root.entropy, spawn_key=tuple(root.spawn_key) + tuple(key))


def stream(root: np.random.SeedSequence, *key: int) -> np.random.Generator:
    """The generator of stream ``key`` under ``root`` (e.g. ``(view, STREAM_CAMERAS)``)."""
    return np.random.default_rng(child_seed(root, *key))


def per_triplet(gens, counts, draw):
    """Concatenate ``draw(gen_t, count_t)`` over triplets (generators ``gens``, one per triplet);
    ``draw`` returns a tuple of arrays with leading axis count_t. Each triplet's draws come from
    its own generator in a fixed order, so they do not depend on the batch."""
    parts = [draw(g, int(c)) for g, c in zip(gens, counts, strict=True)]
    return tuple(np.concatenate([p[k] for p in parts]) for k in range(len(parts[0])))
