"""The qualitative map from all the measurements at once: a joint metric posterior over landmarks
and poses on GTSAM's nonlinear factor graph (:mod:`qfg.nonlinear`), turned into qualitative
states by sampling.

Input (:class:`JointMeasurements`): one :class:`RobotRun` per robot, its poses at the times it
took images, the bearings of every landmark seen in each image, and (optionally) the odometry
between consecutive poses with its per-step noise. Output: a :class:`JointPosterior` over the
landmark positions (and the poses), and from samples of it the state distribution of every
ordered landmark triplet (:func:`triplet_marginals`, a labelled
:class:`qfg.inference.results.Marginals` keyed by landmark ids) and of the cameras
(:func:`camera_marginals`, labelled the same way). The options of the solve are one frozen
:class:`SolveParams` (``solve(measurements, SolveParams(starts=1), seed=0)``).

The method (docs/joint.md has the math and the measurements behind each default):

1. **Per robot, incremental batches.** A robot's poses start from its odometry chain with the
   first pose at the origin; every ``chunk`` poses, landmarks with at least ``min_rays`` rays and
   ``min_parallax_deg`` of parallax (from the current pose estimates) are initialised by
   reweighted ray intersection (:func:`qfg.nonlinear.intersect_rays`), and Levenberg-Marquardt
   refines everything so far (Huber kernel on the bearings); the poses ahead are re-chained from
   the last refined one. No ground truth anywhere.
2. **All robots.** Each robot's map is aligned to the reference robot (the one with most
   landmarks) by a rigid fit on the shared landmarks, then one joint solve with only the
   reference robot's first pose anchored.
3. **Several starts, residual checks.** The joint solve is repeated from starts with every
   landmark's depth halved and doubled (from the poses that see it); a start that ends in a
   different minimum with a cost within ``mode_cost`` of the best becomes a second mode. A
   robot whose whitened bearing residuals have a median above ``residual_limit`` sits in a wrong
   local minimum: it is dropped and the rest re-solved (flag ``local_minimum``). A landmark
   with too few rays is ``unconstrained``; one whose residuals fail the check is
   ``inconsistent``.
4. **Posterior.** The Laplace approximation at each mode (``gtsam.Marginals``: joint landmark
   covariance, scaled by ``inflate``, and by ``inflate_kinematic`` when a run without odometry
   is in the map); modes weighted by ``exp(-cost) sqrt(det Sigma)``. Landmarks
   with few rays (``weak``: fewer than ``sir_rays``) are sampled from their exact conditional
   given the sampled poses (sampling-importance-resampling against the robust bearing
   likelihood), because their depth along the rays is not Gaussian.
5. **States.** Each ordered triplet's EDC state in every sample; triplets touching a flagged or
   unconstrained landmark are mixed toward ``prior_states`` (weight ``widen``; 1 for
   unconstrained), every row toward it with weight ``floor``.

Robots without odometry (MRCLAM dataset 5) are solved with a kinematic motion prior in place
of it, started from the bearings alone at several batch sizes (:mod:`qfg.joint.start`), and
kept only when their maps agree in shape with other robots' (flag ``kinematic``; a lone robot
without odometry cannot be checked and is left out, flag ``unverified``). When nothing can be
solved the posterior has ``method == "none"`` and every triplet is the prior: the
solver-based pipeline must answer (on MRCLAM,
:func:`qfg.datasets.mrclam.joint_map.mrclam_marginals` says which method answered).

Modules, in the order data flows through them: ``inputs`` (:class:`RobotRun`,
:class:`JointMeasurements`, :func:`odometry_steps`, :func:`simulated_measurements`),
``params`` (:class:`SolveParams`, the solve's options), ``start`` (where each robot's solve
starts, with odometry and without), ``solver`` (:func:`solve`), ``posterior``
(:class:`JointPosterior`, :class:`Mode`), ``sampling`` (:func:`sample_landmarks`,
:func:`reference_samples`), ``states`` (:func:`triplet_marginals`, :func:`camera_marginals`),
``moments`` (gauge-free moments and calibration checks:
:func:`ab_frame_moments`, :func:`ab_frame_z2`, :func:`landmark_moments`,
:func:`aligned_errors`, :func:`overdispersion`, :func:`scale_covariance`). The MRCLAM adapter
(its runs as :class:`JointMeasurements`, the joint map as its reference) is
:mod:`qfg.datasets.mrclam.joint_map`, above this package: nothing here reads a dataset.

>>> import numpy as np
>>> from qfg.simulation import random_trajectory_run
>>> run = random_trajectory_run(np.random.default_rng(0), n_landmarks=5, n_poses=30,
...                             fov_deg=360)
>>> post = solve(simulated_measurements(run), seed=0)
>>> post.method, post.flags
('joint', ())
>>> res = triplet_marginals(post, samples=200, seed=0)
>>> res.probabilities.shape
(60, 20)
"""

from .inputs import ODOMETRY_NOISE, JointMeasurements, RobotRun, odometry_steps, simulated_measurements
from .moments import (
    ab_frame_moments,
    ab_frame_z2,
    aligned_errors,
    landmark_moments,
    overdispersion,
    scale_covariance,
)
from .params import SolveParams
from .posterior import JointPosterior, Mode
from .sampling import reference_samples, sample_landmarks
from .solver import KINEMATIC_INFLATE, OUTLIER, OUTLIER_SHARE, OVERDISPERSED, solve
from .states import FLOOR, camera_marginals, triplet_marginals

__all__ = ["RobotRun", "JointMeasurements", "Mode", "JointPosterior", "SolveParams", "solve",
           "sample_landmarks", "triplet_marginals", "camera_marginals", "odometry_steps",
           "simulated_measurements",
           "reference_samples", "ab_frame_moments", "ab_frame_z2", "landmark_moments",
           "aligned_errors", "overdispersion", "scale_covariance",
           "ODOMETRY_NOISE", "FLOOR", "OUTLIER", "OUTLIER_SHARE", "KINEMATIC_INFLATE",
           "OVERDISPERSED"]
