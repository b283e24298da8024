"""Algorithm 1 of Mor and Indelman: sequential importance sampling over camera trajectories,
batched over triplets; the engine of ``method="full"`` and of the default ``method="fast"`` (the
same with small budgets).

The target (AB frame, A = (0, 0), B = (0, 1); angles in radians, lengths in |AB|) is the
posterior of the configuration [C, X_1..X_n] given the history H,

    p(C, X_1:n | H)  ∝  prior(C, X_1..X_n) prod_t N(phi_t - f(C, X_t); sigma_v)
                        prod_t N(psi_t - g(X_t+1, X_t); sigma_w)

(bearings phi_t of A, B and C from pose X_t, headings psi_t between consecutive poses, uniform
camera headings), and the answer its state probabilities ``P(S^{AB:C} | H)`` and
``P(S^{AB:X}_i | H)``. Per view i of every triplet:

* sampling step (view 1, :func:`.engine.start`): ``n_samples`` camera poses near the locus arc
  of (phi_A, phi_B): the bearings to A and B drawn from N(measured, sigma_v^2), a position on the
  drawn arc at a stratified arc parameter (:func:`.arcs.arc_parameter`), the heading from phi_A.
  The importance weight is the arc's change of variables times the per-point prior.
* motion step (views 2..n, :mod:`.motion`): for each hypothesis, ``motion_samples`` draws of the
  heading noise and of the view's A/B bearing noise; the ray from X_{i-1} along
  ``alpha_{i-1} + psi + eps`` meets the drawn locus arc at 0, 1 or 2 points, each a new
  hypothesis. The drawn noise carries the heading and A/B likelihoods exactly; the weight is the
  change of variables ``t / |grad Gamma . u|`` (:func:`.arcs.log_ray_jacobian`) times the
  per-point prior.
* odometry distances (optional, views 3..n): the weight also carries
  :func:`.odometry.log_distance_factor` of the step-length ratio; such triplets draw some of
  their children at the step length the distance ratio predicts instead of along the heading (a
  circle about X_{i-1} meets the arc), weighted by the balance heuristic
  (:mod:`.distance_proposal`).
* noise models (optional): one heading sigma per step (``SISState.step_sigma``, the step's
  column going in before its motion step), a two-normal tail on the step-length ratio
  (``distance_tail``: a factor in the weights) and on the headings (``heading_tail``: the motion
  step draws from the mixture, so the weights again carry no heading factor).
* C (views 2..n, :mod:`.c_integral`): its integral
  ``∫ p1(L) prod_t N(phi_C,t - f(L, X_t); sigma_v) dL`` is estimated with ``landmark_samples``
  draws from a defensive mixture (Laplace Gaussian about the triangulation, and draws along the
  lines of sight: :func:`.landmarks.sample_landmarks`), which stays right when the lines of
  sight coincide. Every view costs the same whatever the views so far: where C's depth is
  resolved a hypothesis carries a Gaussian summary of C's integral (mode, information, log
  integral) that each child updates with its one new line of sight
  (:func:`.laplace.update_landmark`, O(1)); only hypotheses without one (the second view, an
  unresolved depth, a bearing tail) are refitted over their latest views (at most
  :data:`.motion.REFIT_VIEWS`). Trajectories are kept as ancestry (``levels``: per view the
  poses and each one's parent, :mod:`.state`), so a step adds one level and copies no past pose;
  whole trajectories are gathered only for the final sample, refits and moves
  (:func:`.state.trajectories`).
* pruning and resampling per triplet (:mod:`.resampling`): hypotheses below ``prune_ratio`` x
  the heaviest are dropped; above ``max_hypotheses`` the set is resampled (systematic), the C
  weight divided out as in sequential importance resampling; with ``rejuvenate`` or
  ``move_steps`` the resampled hypotheses are moved by Metropolis-Hastings steps that leave the
  target invariant (:mod:`.moves`, :mod:`.rejuvenation`).

These intermediate weights use a per-point prior ``p1`` (:func:`.prior.point_log_prior`;
:mod:`.target`). The answer does not: :func:`.engine.finish` resamples ``posterior_samples``
trajectories per triplet, draws C for each, and weights every (trajectory, C) sample by the
prior's ``log_density`` of the whole configuration [C, X_1..X_n] over the intermediate target,
so the estimate targets the exact posterior under any :class:`qfg.priors.Prior`.

Every random draw of triplet t at view i comes from its own stream
``SeedSequence(root_t, spawn_key=(i, purpose))``, so a triplet solved alone, in a batch, or view
by view gives the same numbers. Views whose three bearings repeat the previous view's exactly are
taken as the camera not having moved (flagged). With both sigmas zero a triplet draws no noise in
the motion step (one child per hypothesis) and spends the same budget on the first view
(``n_samples x motion_samples``). Likelihood widths are ``max(sigma, floor)``.

Around the engine: :mod:`.populations` solves a triplet as ``populations`` independent runs and
averages them; :mod:`.escalation` solves again with the whole budget the few-views answers whose
populations disagree; :mod:`.model_check` checks the bearings and headings against the model.

Modules, by job: :mod:`.engine` (``start``, ``step``, ``finish``), :mod:`.state`,
:mod:`.motion`, :mod:`.distance_proposal`, :mod:`.c_integral`, :mod:`.landmarks`,
:mod:`.target`, :mod:`.resampling`, :mod:`.moves`, :mod:`.rejuvenation`, :mod:`.populations`,
:mod:`.escalation`, :mod:`.model_check`.
"""
