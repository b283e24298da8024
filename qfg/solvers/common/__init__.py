"""Pieces several solver methods share, one job per module:

* :mod:`.input`: the measurements' checks (:class:`.input.Measurements`) and the partition;
* :mod:`.options`: the methods, their default options and the checks of user options;
* :mod:`.likelihood`: bearing likelihoods (normal and heavy-tailed), log-sum-exp;
* :mod:`.odometry`: the factor on the ratio of consecutive step lengths;
* :mod:`.prior`: the solvers' use of :mod:`qfg.priors` (per-point and joint priors);
* :mod:`.arcs`: the locus arcs of two bearings, rays meeting them and their Jacobians;
* :mod:`.laplace`: C's triangulation and Laplace approximation (and its carried summary);
* :mod:`.degenerate`: geometry flags (coincident lines of sight, repeated views, ...);
* :mod:`.estimate`: the answer (:class:`.estimate.TripletEstimate`, :class:`.estimate.Hypotheses`)
  and its pooling;
* :mod:`.histograms`: weighted state histograms with their Monte Carlo error;
* :mod:`.diagnostics`: importance-sampling diagnostics (Pareto k);
* :mod:`.seeds`: the random streams, one per (view, purpose).
"""
