"""The options of the joint solve (:func:`qfg.joint.solve`) as one frozen parameter object,
:class:`SolveParams`, as GTSAM's ``LevenbergMarquardtParams`` are: every option with its
default, documented and checked once, so that a solve's settings can be built, compared,
stored and passed on (``qfg.datasets.mrclam.joint_map.mrclam_marginals(params=...)``) as one
value. The seed and the progress callback are per call, not options: they are arguments of
:func:`qfg.joint.solve` itself.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from .. import nonlinear as _nl
from .._validate import non_negative, positive_int
from . import start as _start

__all__ = ["SolveParams", "OUTLIER", "KINEMATIC_INFLATE"]

#: Bearings beyond this many sigmas at a fit are gross errors (misread barcodes and the like):
#: the Huber kernel bounds their pull but does not remove it, so they are left out and the fit
#: redone (docs/joint.md, "Outlier rejection").
OUTLIER = 4.0
#: Factor on the covariance of a map that holds a run solved with the kinematic prior (no
#: odometry), or ``"auto"``: the robots' own maps' scatter about the joint map
#: (:func:`qfg.joint.overdispersion`) when above 1. The kinematic prior is a guess at the
#: motion, and the Laplace approximation of such a map is more certain of its relative landmark
#: positions than their errors warrant; the robots' own maps measure how much more without
#: ground truth (docs/joint.md, "Without odometry").
KINEMATIC_INFLATE = "auto"


@dataclass(frozen=True)
class SolveParams:
    """Every option of :func:`qfg.joint.solve`, with its default (frozen; checked at
    construction: a bad value is a ``ValueError`` naming the field). Change one with
    ``dataclasses.replace(params, starts=1)`` (checked again).

    >>> p = SolveParams(starts=1)
    >>> p.starts, p.chunk, p.outlier
    (1, 100, 4.0)
    >>> SolveParams(chunk=1)
    Traceback (most recent call last):
    ...
    ValueError: chunk: expected an integer >= 2, got 1

    Attributes:
        chunk: poses per incremental batch of a run (an int >= 2).
        min_rays: rays a landmark needs before it is initialised (an int >= 2).
        min_parallax_deg: parallax a landmark needs before it is initialised: the largest angle
            between two of its rays, modulo 180 degrees (degrees, >= 0).
        starts: joint solves, an int >= 1 (1: the incremental start only; 2 adds every
            landmark's depth halved, 3 or more also doubled).
        robust: Huber threshold on the bearings (sigmas, >= 0; 0: plain least squares).
        outlier: bearings with a whitened residual above it are left out and the fit redone,
            at the end of each run's batches and after the joint solve (sigmas, >= 0; 0: keep
            all; default :data:`OUTLIER`).
        residual_limit: a robot whose median absolute whitened bearing residual exceeds it, or with
            more than :data:`qfg.joint.OUTLIER_SHARE` of its bearings beyond ``outlier``, is in
            a wrong local minimum (sigmas, >= 0; a Gaussian gives a median of 0.67).
        landmark_limit: a landmark whose median absolute whitened residual exceeds it is
            ``inconsistent`` (sigmas, >= 0).
        mode_cost: another start's minimum within this much cost (the robust negative log
            likelihood, >= 0) of the best is kept as a second mode.
        inflate: factor on every covariance (>= 0; 1: the Laplace approximation as is).
        inflate_kinematic: a further factor on the covariance (>= 0; 1: none) when a run solved
            with the kinematic prior is in the map, or ``"auto"`` (the default,
            :data:`KINEMATIC_INFLATE`): the robots' own maps' scatter about the joint map
            (:func:`qfg.joint.overdispersion`) when it exceeds 1 (flag ``overdispersed`` above
            :data:`qfg.joint.OVERDISPERSED`). The scatter is measured on every map of two or
            more robots (``info["overdispersion"]``; NaN when too few triplets are placed by two
            of them) and reported, not acted on, when every run has odometry.
        sir_rays: landmarks with fewer rays are ``weak``, sampled from their exact conditional
            (an int >= 0; 0: none).
        max_iterations: Levenberg-Marquardt iterations per solve (an int >= 1).
        without_odometry: ``"kinematic"``: a run without odometry is solved with the
            ``kinematic`` motion prior in its place (:mod:`qfg.joint.start`), started at each of
            ``kinematic_chunks`` batch sizes (the fit of least cost kept), and used only if its
            map agrees with other robots' (``agree``); ``"skip"``: left out (flag
            ``no_odometry``).
        kinematic: the motion prior of a run without odometry (a
            :class:`qfg.joint.start.KinematicPrior`; default :data:`qfg.joint.start.KINEMATIC`).
        kinematic_chunks: batch sizes (poses, each an int >= 2) of the start without odometry;
            the fit of least cost is kept. Stored as a tuple of ints.
        agree: tolerance (a share of the map's size, >= 0) of the check that keeps a run
            without odometry only if it is in the largest group of robots whose maps agree
            pairwise (:func:`qfg.joint.start.agreeing_group`; default
            :data:`qfg.joint.start.AGREE`); a fit without odometry can pass every residual
            check in a wrong minimum, so a lone run without odometry is left out (flag
            ``unverified``). None: no check (every such run kept, at the user's risk).
        too_close: a pose fitted closer to a landmark it sees than this share of the median
            range of all bearings is moved off it (:func:`qfg.joint.start.escape_close`; in
            [0, 1), 0: not checked; default :data:`qfg.joint.start.TOO_CLOSE`);
            ``info["too_close"]`` counts such bearings, ``info["too_close_dropped"]`` those left
            out because the fit returned to them.
    """

    chunk: int = 100
    min_rays: int = 3
    min_parallax_deg: float = 10.0
    starts: int = 3
    robust: float = _nl.HUBER_K
    outlier: float = OUTLIER
    residual_limit: float = 2.0
    landmark_limit: float = 3.0
    mode_cost: float = 10.0
    inflate: float = 1.0
    inflate_kinematic: float | str = KINEMATIC_INFLATE
    sir_rays: int = 20
    max_iterations: int = 100
    without_odometry: str = "kinematic"
    kinematic: _start.KinematicPrior = _start.KINEMATIC
    kinematic_chunks: tuple = (25, 50, 100)
    agree: float | None = _start.AGREE
    too_close: float = _start.TOO_CLOSE

    def __post_init__(self):
        def put(name, value):
            object.__setattr__(self, name, value)

        put("chunk", positive_int("chunk", self.chunk, minimum=2))
        put("min_rays", positive_int("min_rays", self.min_rays, minimum=2))
        put("min_parallax_deg", non_negative("min_parallax_deg", self.min_parallax_deg))
        put("starts", positive_int("starts", self.starts))
        for name in ("robust", "outlier", "residual_limit", "landmark_limit", "mode_cost",
                     "inflate"):
            put(name, non_negative(name, getattr(self, name)))
        if isinstance(self.inflate_kinematic, str):
            if self.inflate_kinematic != "auto":
                raise ValueError(f"inflate_kinematic: expected a factor >= 0 or 'auto', got "
                                 f"{self.inflate_kinematic!r}")
        else:
            put("inflate_kinematic", non_negative("inflate_kinematic", self.inflate_kinematic))
        put("sir_rays", positive_int("sir_rays", self.sir_rays, minimum=0))
        put("max_iterations", positive_int("max_iterations", self.max_iterations))
        if self.without_odometry not in ("kinematic", "skip"):
            raise ValueError(f"without_odometry: expected 'kinematic' or 'skip', got "
                             f"{self.without_odometry!r}")
        if not isinstance(self.kinematic, _start.KinematicPrior):
            raise ValueError(f"kinematic: expected a qfg.joint.start.KinematicPrior, got "
                             f"{type(self.kinematic).__name__}")
        try:
            chunks = np.atleast_1d(self.kinematic_chunks).tolist()
        except (TypeError, ValueError):
            raise ValueError(f"kinematic_chunks: expected batch sizes (ints >= 2), got "
                             f"{self.kinematic_chunks!r}") from None
        put("kinematic_chunks", tuple(positive_int("kinematic_chunks", c, minimum=2)
                                      for c in chunks))
        if self.agree is not None:
            put("agree", non_negative("agree", self.agree))
        put("too_close", non_negative("too_close", self.too_close))
        if self.too_close >= 1:
            raise ValueError(f"too_close: expected a share of the median range in [0, 1), got "
                             f"{self.too_close!r}")



def _removed_options(function: str, names) -> TypeError:
    """The error for options passed to ``function`` as keywords of their own (the form before
    :class:`SolveParams`): one line naming the new form and CHANGELOG.md, or Python's own
    message for a keyword that never was an option."""
    names = sorted(names)
    known = {f.name for f in dataclasses.fields(SolveParams)}
    unknown = [n for n in names if n not in known]
    if unknown:
        return TypeError(f"{function}() got an unexpected keyword argument {unknown[0]!r}")
    args = ", ".join(f"{n}=..." for n in names)
    return TypeError(f"{function}(): {', '.join(names)}: options of qfg.joint.SolveParams now, "
                     f"pass params=SolveParams({args}) (CHANGELOG.md)")
