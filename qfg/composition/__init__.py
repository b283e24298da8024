"""Composition tensors: offline build, shipped files, online probabilistic composition.

For three triplets sharing landmarks pairwise, t1 = AB:C, t2 = BC:D, t3 = AB:D, the composition
tensor ``T[i, j, k]`` (m x m x m) is the probability that the three triplets are in states
(i, j, k) when C is uniform in state i of AB:C and D uniform in the AB window (and in the BC
window) -- conventions.md, "Composition tensor"; paper section 5a. It is computed offline once per
partition (:mod:`qfg.composition.build`, ``qfg tensors build``), shipped as ``tensors/<name>.npz``
and loaded with :func:`tensor`. Online, :func:`marginal`, :func:`joint` and :func:`feasible` combine
it with per-triplet estimates, batched over many factors.

>>> import numpy as np
>>> from qfg import composition
>>> T = composition.tensor("edc")                                  # doctest: +SKIP
>>> V1 = np.eye(20)[2]; V2 = np.full(20, 1 / 20)                     # doctest: +SKIP
>>> composition.marginal(T, V1, V2, role=3).p.shape                 # doctest: +SKIP
(20,)
"""

from .online import Feasible, Joint, Marginal, as_table, feasible, joint, marginal
from .store import (
    ENV_VAR,
    CompositionTensor,
    TensorFileError,
    checksum,
    load,
    rebuild_command,
    save,
    tensor,
    tensor_path,
    tensors_dir,
)

__all__ = [
    "CompositionTensor", "TensorFileError", "ENV_VAR",
    "tensor", "load", "save", "checksum", "tensor_path", "tensors_dir", "rebuild_command",
    "Marginal", "Joint", "Feasible", "marginal", "joint", "feasible", "as_table",
]
