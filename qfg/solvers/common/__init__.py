"""Pieces several solver methods share, one job per module:

* :mod:`.input`: checks of one triplet's measurements (:class:`.input.Measurements`) and the
  partition;
* :mod:`.options`: the methods, their documented default options and the checks of user options;
* :mod:`.likelihood`: likelihood arithmetic in log space (the Gaussian kernel, heavy-tailed
  bearing noise, log-sum-exp);
* :mod:`.odometry`: the factor on the ratio of consecutive step lengths given the travelled
  distances;
* :mod:`.prior`: priors over AB-frame configurations as the solvers use them (the per-point
  prior of intermediate weights, the exact joint prior of final weights);
* :mod:`.arcs`: positions on the locus arcs of (phi_A, phi_B), points along lines of sight, and
  the change-of-variables densities that make them importance samples;
* :mod:`.laplace`: the Laplace approximation of C given camera poses (triangulation, C's
  integral, its depth spread, the summary carried from view to view);
* :mod:`.degenerate`: degenerate geometry seen in the measurements alone, the flags every solver
  attaches;
* :mod:`.estimate`: the answer (:class:`.estimate.TripletEstimate`, the
  :class:`.estimate.Hypotheses` behind it) and how every solver builds and pools it;
* :mod:`.histograms`: weighted state histograms and their Monte Carlo error;
* :mod:`.diagnostics`: importance-sampling diagnostics (the Pareto k-hat of the weights);
* :mod:`.seeds`: the random streams, one per (view, purpose).
"""
