"""The samples of configuration inference and what they answer (:mod:`qfg.configurations`):
:class:`ConfigurationPosterior`, its marginals of any triplets (seen or not), the leave-one-out
check, the likelihood of given configurations, and more evidence tempered in from its particles
(:meth:`ConfigurationPosterior.update`).
"""

from __future__ import annotations

import warnings

import numpy as np

from .._validate import as_float_array, as_rng, non_negative
from .check import LeaveOneOutCheck, prior_mixing_weight
from .evidence import (
    _as_triplet,
    _concat_terms,
    _evidence_items,
    _lookup_of,
    _make_terms,
    _term_loglik,
    _Terms,
)
from .sampler import _Sampler

__all__ = ["ConfigurationPosterior", "NotSettledWarning", "UNSETTLED_ERROR", "UNSETTLED_SHARE"]

#: A row of :meth:`ConfigurationPosterior.marginals` is *unsettled* when its largest Monte Carlo
#: error (the spread of the populations' answers) is above this: the ``widen`` of the MRCLAM
#: maps, i.e. the rows that widening replaces by the prior's states there. (Small maps at the
#: default budget have errors of 0.01-0.04.)
UNSETTLED_ERROR = 0.05
#: Share of unsettled rows above which :meth:`ConfigurationPosterior.marginals` warns
#: (:class:`NotSettledWarning`). MRCLAM's chains of landmarks (datasets 1 and 2) leave a
#: quarter to four fifths of the map's rows more than half widened even under correct evidence
#: (docs/configurations.md, "How strong the seen evidence must be").
UNSETTLED_SHARE = 0.25


class NotSettledWarning(UserWarning):
    """The sampler's populations disagree on many rows of the marginals: their answers there are
    one population's guess (or, with ``widen``, mostly the prior's states)."""


#: Elements (particles x triplets) per block when the states of many triplets are looked up.
_CHUNK = 1 << 21


class ConfigurationPosterior:
    """Weighted samples of the landmarks' world positions given the seen triplets' evidence.

    Attributes:
        landmarks: tuple of landmark ids (column order of ``positions``).
        positions: (P, n, 2) world positions (the prior's box units), read-only.
        weights: (P,) normalized weights (equal after the final resampling).
        groups: (P,) int, the independent population of each particle.
        partition, prior: the partition and :class:`qfg.priors.WorldBoxPrior` used.
        method: ``"config-state"`` or ``"config-metric"`` (the seen triplets' state or metric
            likelihood; the marginals' ``method``).
        evidence: {triplet: (m,) vector or PositionSummary}, the seen triplets' evidence.
        diagnostics: dict -- ``n_stages``, ``betas``, ``ess`` (fraction of each stage's
            particles, before resampling), ``acceptance_landmark`` / ``acceptance_similarity``
            (mean acceptance of the moves), ``log_evidence`` (per group, the SMC estimate of
            log E_prior[prod L]), ``options``.

    :meth:`marginals` gives any triplets' state distributions, :meth:`update` adds evidence.
    """

    def __init__(self, landmarks, X, groups, part, pr, method, terms, options, diag, q):
        self.landmarks = tuple(landmarks)
        self._index = {l: i for i, l in enumerate(self.landmarks)}
        X = np.array(X)
        X.setflags(write=False)
        self.positions = X
        self._Xt = np.ascontiguousarray(np.transpose(X, (1, 0, 2)))
        self.weights = np.full(X.shape[0], 1.0 / X.shape[0])
        self.weights.setflags(write=False)
        self.groups = np.asarray(groups)
        self.partition, self.prior, self.method = part, pr, method
        self._terms, self.options, self.diagnostics, self._q = terms, options, diag, q

    @property
    def evidence(self) -> dict:
        return dict(zip(self._terms.triplets, self._terms.evidence, strict=True))

    def __repr__(self):
        return (f"ConfigurationPosterior(landmarks={len(self.landmarks)}, "
                f"particles={self.positions.shape[0]}, seen={len(self._terms.triplets)}, "
                f"method={self.method!r}, stages={self.diagnostics.get('n_stages')})")

    def _indices(self, triplets):
        out = np.zeros((len(triplets), 3), dtype=np.intp)
        for r, t in enumerate(triplets):
            for a, x in enumerate(t):
                try:
                    out[r, a] = self._index[x]
                except KeyError:
                    raise KeyError(f"triplet: {t} uses landmark {x}, which is not in this "
                                   f"configuration (landmarks {self.landmarks[:10]}"
                                   f"{'...' if len(self.landmarks) > 10 else ''})") from None
        return out

    def states(self, triplets) -> np.ndarray:
        """(P, len(triplets)) int states of the triplets in every sampled configuration."""
        ts = [_as_triplet(t) for t in triplets]
        return self._states(self._indices(ts))

    def _states(self, ijk):
        return self._states_t(ijk).T

    def _states_t(self, ijk):
        """(r, P) states, from the landmark-major copy (whole-row gathers)."""
        from ..geometry import to_frame

        Xt = self._Xt
        return self.partition.state_of(to_frame(Xt[ijk[:, 2]], Xt[ijk[:, 0]], Xt[ijk[:, 1]]))

    def log_likelihoods(self, positions=None) -> np.ndarray:
        """(T, K) ``log L_t(X_k)``: each seen triplet's floored likelihood term
        (:mod:`qfg.configurations`; the state kind tempered and floored exactly as the sampler used
        it) at K configurations.

        ``positions``: (K, n, 2) or (n, 2) world positions, columns in the order of
        :attr:`landmarks` (default: the sampled configurations). Rows follow the seen triplets of
        :attr:`evidence`. Any configuration can be scored: the ground truth, to ask whether a
        miss is the sampler's (the truth's ``sum_t log L_t`` above the particles') or the
        evidence's (below them). Only AB-frame positions enter, so a similarity transform of a
        configuration leaves every term unchanged.

        >>> from qfg.configurations import infer_configurations
        >>> post = infer_configurations({(0, 1, 2): np.eye(20)[1] * 0.9 + 0.005}, n_particles=40,
        ...                             seed=0)
        >>> post.log_likelihoods(np.array([[0.0, 0.0], [0.0, 1.0], [-0.5, 0.5]])).shape
        (1, 1)
        """
        if positions is None:
            Xt = self._Xt
        else:
            X = as_float_array("positions", positions)
            if X.ndim == 2:
                X = X[None]
            n = len(self.landmarks)
            if X.ndim != 3 or X.shape[1:] != (n, 2):
                raise ValueError(f"positions: expected shape (K, {n}, 2) or ({n}, 2), the "
                                 f"landmarks' world positions in the order of .landmarks; got "
                                 f"{np.shape(positions)}")
            Xt = np.ascontiguousarray(np.transpose(X, (1, 0, 2)))
        t = self._terms
        idx = np.arange(len(t.triplets))
        return _term_loglik(t, idx, [Xt[t.ijk[:, a]] for a in range(3)], _lookup_of(self.partition))

    def all_triplets(self) -> list:
        """Every ordered triplet of this configuration's landmarks (n (n-1) (n-2))."""
        L = self.landmarks
        return [(a, b, c) for a in L for b in L for c in L if a != b and b != c and a != c]

    def components(self) -> np.ndarray:
        """(n,) int, the connected component of each landmark (column of ``positions``) in the
        graph that links the landmarks of every seen triplet; a landmark in no seen triplet is
        a component of its own.

        >>> from qfg.configurations import infer_configurations
        >>> post = infer_configurations({(0, 1, 2): np.full(20, 0.05)}, landmarks=range(4),
        ...                             n_particles=40, seed=0)
        >>> post.components().tolist()
        [0, 0, 0, 1]
        """
        par = list(range(len(self.landmarks)))

        def find(i):
            while par[i] != i:
                par[i] = par[par[i]]
                i = par[i]
            return i

        for t in self._terms.ijk:
            for x in t[1:]:
                par[find(int(x))] = find(int(t[0]))
        roots = [find(i) for i in range(len(par))]
        return np.unique(roots, return_inverse=True)[1].astype(np.intp)

    def marginals(self, triplets=None, *, pseudo_count=None, widen=None, unlinked="sample",
                  check=False):
        """:class:`qfg.inference.Marginals` of ``triplets`` (default: every ordered triplet of
        the landmarks), seen and unseen alike.

        Each row is the particles' state histogram shrunk toward the prior's state distribution
        by ``pseudo_count`` pseudo-draws, ``(P f + a q) / (P + a)`` (no state the particles missed
        is given probability 0). ``info``: ``mc_error`` (n, m) the standard error from the
        spread of the ``n_groups`` populations' estimates, ``mc_error_max``, ``seen`` (n,) bool,
        the sampler's diagnostics and ``configurations`` (this object).

        ``widen`` (None: off): a row whose populations disagree is not trusted. Each row is mixed
        toward the prior's state distribution, ``(1 - w) f + w q`` with ``w = min(1, e / widen)``
        and ``e`` the row's largest Monte Carlo error: where the sampler has not settled (e.g.
        clusters of landmarks tied by few seen triplets, whose relative placement the
        populations choose differently), the answer says "unknown" instead of picking one
        population's guess. ``info["widened"]``: (n,) the weights ``w``.

        ``unlinked``: the answer for a triplet whose landmarks lie in different connected
        components of the evidence (:meth:`components`), about whose relative placement only the
        prior speaks: ``"sample"`` (the samples, i.e. the world prior's model of where unlinked
        groups lie) or ``"prior"`` (the prior's state distribution ``q``: "unknown", for data whose
        landmarks the i.i.d. box prior does not describe, e.g. an arena's). ``info["unlinked"]``:
        (n,) bool.

        ``check``: when True, every row is mixed toward ``q`` by the weight
        :meth:`loo_check` finds (0 when the seen triplets predict each other at least as well as
        the prior does); ``info["check"]``: the :class:`LeaveOneOutCheck`.

        ``info["unsettled"]``: (n,) bool, rows whose largest Monte Carlo error is above
        :data:`UNSETTLED_ERROR` (not the unlinked rows with ``unlinked="prior"``); a
        :class:`NotSettledWarning` when they are more than :data:`UNSETTLED_SHARE` of the rows.
        """
        if unlinked not in ("sample", "prior"):
            raise ValueError(f"unlinked: expected 'sample' or 'prior', got {unlinked!r}")
        from ..inference.results import Marginals

        if triplets is None:
            triplets = self.all_triplets()
        ts = [_as_triplet(t) for t in triplets]
        ijk = self._indices(ts)
        a = float(self.options["pseudo_count"] if pseudo_count is None else
                  non_negative("pseudo_count", pseudo_count))
        m, P = self.partition.n_states, self.positions.shape[0]
        G = int(self.groups.max()) + 1
        R = len(ts)
        counts = np.zeros((G, R, m))
        step = max(1, _CHUNK // P)
        for r0 in range(0, R, step):
            s = self._states_t(ijk[r0:r0 + step])                         # (r, P)
            r = s.shape[0]
            flat = (self.groups[None, :] * r + np.arange(r)[:, None]) * m + s
            counts[:, r0:r0 + r] = np.bincount(flat.ravel(), minlength=G * r * m
                                               ).reshape(G, r, m)
        Pg = P // G
        fg = (counts + (a / G) * self._q) / (Pg + a / G)                  # per group, shrunk
        f = (counts.sum(axis=0) + a * self._q) / (P + a)
        se = np.std(fg, axis=0, ddof=1) / np.sqrt(G) if G > 1 else np.full((R, m), np.nan)
        seen = set(self._terms.triplets)
        info = dict(self.diagnostics)
        if widen is not None:
            widen = non_negative("widen", widen)
            if not widen > 0:
                raise ValueError("widen: expected a number > 0 (or None: off)")
            if G < 2:
                raise ValueError("widen: needs n_groups >= 2 (the error is their spread)")
            w = np.minimum(1.0, se.max(axis=1, initial=0.0) / widen)[:, None]
            f = (1.0 - w) * f + w * self._q
            info["widened"] = w[:, 0]
        comp = self.components()[ijk]
        cut = (comp[:, 0] != comp[:, 1]) | (comp[:, 0] != comp[:, 2])
        if unlinked == "prior" and cut.any():
            f[cut] = self._q
        info["unlinked"] = cut
        if check:
            chk = self.loo_check()
            f = (1.0 - chk.widen) * f + chk.widen * self._q
            info["check"] = chk
        unsettled = se.max(axis=1, initial=0.0) > UNSETTLED_ERROR if G > 1 else np.zeros(R, bool)
        if unlinked == "prior":
            unsettled &= ~cut   # answered by q, whatever the populations say
        if R and unsettled.mean() > UNSETTLED_SHARE:
            warnings.warn(
                f"configuration marginals: the sampler's {G} populations disagree on "
                f"{unsettled.sum()} of {R} rows (Monte Carlo error above {UNSETTLED_ERROR}); "
                + ("they are mixed toward the prior's states (widen), " if widen is not None
                   else "they are one population's guess, ")
                + "so more particles or sweeps (n_particles, n_sweeps) may sharpen them; on real "
                "data check that a settled answer is not confidently wrong "
                "(docs/configurations.md)", NotSettledWarning, stacklevel=2)
        info.update(mc_error=se, mc_error_max=float(np.max(se)) if se.size else 0.0,
                    unsettled=unsettled, seen=np.array([t in seen for t in ts], dtype=bool),
                    configurations=self)
        return Marginals(tuple(ts), self.partition.name, f, self.method, info)

    def loo_check(self) -> LeaveOneOutCheck:
        """Leave-one-out check of the model against the seen triplets (no ground truth).

        Each seen triplet's evidence is predicted by the configurations the other seen triplets
        give: with ``L_t`` its likelihood (normalized: mean 1 under the prior), the posterior
        without ``t`` is the posterior reweighted by ``1 / L_t``, and its prediction of ``t``'s
        data relative to the prior's is the harmonic mean (the conditional predictive ordinate)

            m_t = E_{pi_-t}[L_t] = 1 / E_pi[1 / L_t]

        (bounded: ``L_t`` is floored). Mixing the configurations with the prior by ``lam`` (every
        marginal ``(1 - lam) f + lam q``) predicts ``(1 - lam) m_t + lam``; ``widen`` is the ``lam``
        of :data:`CHECK_GRID` with the best mean log prediction. Under a correct model the seen
        triplets predict each other better than the prior (``mean(1 / m_t)`` about 1, ``widen``
        near 0); when they contradict each other under it (wrong estimates, a prior that does
        not describe the landmarks), ``widen`` grows toward 1: "unknown" instead of a confident
        answer the evidence does not support.

        >>> from qfg.configurations import infer_configurations
        >>> post = infer_configurations({(0, 1, 2): np.eye(20)[1] * 0.9 + 0.005,
        ...                              (0, 1, 3): np.eye(20)[1] * 0.9 + 0.005},
        ...                             n_particles=400, seed=0)
        >>> chk = post.loo_check()
        >>> chk.log_cpo.shape, 0.0 <= chk.widen <= 1.0
        ((2,), True)
        """
        t = self._terms
        T = len(t.triplets)
        if T == 0:
            return LeaveOneOutCheck((), np.zeros(0), 0.0, (0.0, 0.0))
        lookup = _lookup_of(self.partition)
        w = np.asarray(self.weights, dtype=float)
        log_cpo = np.empty(T)
        step = max(1, _CHUNK // self.positions.shape[0])
        for r0 in range(0, T, step):
            idx = np.arange(r0, min(T, r0 + step))
            pts = [self._Xt[t.ijk[idx, a]] for a in range(3)]
            ll = _term_loglik(t, idx, pts, lookup)                      # (r, P)
            # log 1 / E_w[exp(-ll)], stably
            neg = -ll
            mx = neg.max(axis=1, keepdims=True)
            log_cpo[idx] = -(mx[:, 0] + np.log(np.exp(neg - mx) @ w))
        lam, agreement = prior_mixing_weight(log_cpo)
        return LeaveOneOutCheck(tuple(t.triplets), log_cpo, lam, agreement)

    def update(self, evidence, *, seed=0, landmarks=(), ess=None) -> "ConfigurationPosterior":
        """A new posterior with more evidence, tempered in from these particles (cheaper than a
        restart when the new evidence is a small part of the whole).

        ``evidence``: {triplet: estimate} as in :func:`infer_configurations`; a triplet already
        seen has its old evidence replaced (the old likelihood tempered out while the new one
        comes in). Landmarks new to the map get positions drawn from the prior given the others.
        ``seed``: int, SeedSequence or Generator (default 0).
        """
        o = self.options
        rng = as_rng(seed)
        items = _evidence_items(evidence, self.partition, self.prior,
                                self.method.removeprefix("config-"), ess)
        new_ids = [x for x in dict.fromkeys([*landmarks, *(x for t in items for x in t)])
                   if x not in self._index]
        ids = self.landmarks + tuple(new_ids)
        index = {l: i for i, l in enumerate(ids)}
        X = np.array(self.positions)
        if new_ids:
            X = np.concatenate([X, _prior_extension(self.prior, X, len(new_ids), rng)], axis=1)
        old = _Terms(**{k: getattr(self._terms, k) for k in (
            "ijk", "logtab", "ratiotab", "eps", "metric", "mix", "centres", "logw", "lin", "lnorm",
            "kind")}, triplets=list(self._terms.triplets), evidence=list(self._terms.evidence))
        old.kind = np.where(np.isin(np.arange(len(old.triplets)),
                                    [i for i, t in enumerate(old.triplets) if t in items]),
                            2, 0).astype(np.int8)
        new = _make_terms(items, index, self._q, o, 1)
        terms = _concat_terms(old, new) if len(old.triplets) else new
        return _run(ids, X, terms, self.partition, self.prior, self.method, o, self._q, rng,
                    self.groups)


def _prior_extension(pr, X, k, rng):
    """(P, k, 2) positions of k new landmarks from the box prior given the configurations X."""
    P = X.shape[0]
    out = rng.uniform((0.0, 0.0), (pr.width, pr.height), size=(P, k, 2))
    if pr.d_min <= 0:
        return out
    for j in range(k):
        for _ in range(1000):
            others = np.concatenate([X, out[:, :j]], axis=1)
            d = np.sqrt(np.min(np.sum((others - out[:, j:j + 1]) ** 2, axis=-1), axis=1))
            bad = d < pr.d_min
            if not bad.any():
                break
            out[bad, j] = rng.uniform((0.0, 0.0), (pr.width, pr.height), size=(int(bad.sum()), 2))
    return out


def _run(ids, X, terms, part, pr, method, options, q, rng, groups):
    G = options["n_groups"]
    s = _Sampler(np.array(X, dtype=float), terms, part, pr, options["floor"], rng, G,
                 bool(options["block_moves"]))
    betas, esss, logz = s.run(options["target_ess"], options["n_sweeps"])
    if len(betas) > 1:
        # after the last stage the particles have moved once; one more sweep decorrelates the
        # duplicates resampling made
        s.sweep(1.0, options["n_sweeps"])
    keep = terms.kind != 2
    terms = terms.subset(keep)
    terms.kind = np.zeros(len(terms.triplets), dtype=np.int8)
    diag = {"n_stages": len(betas) - 1, "betas": np.array(betas), "ess": np.array(esss),
            "acceptance_landmark": float(np.mean(s.acc_land)) if s.acc_land else float("nan"),
            "acceptance_similarity": float(np.mean(s.acc_sim)) if s.acc_sim else float("nan"),
            "acceptance_block": float(np.mean(s.acc_block)) if s.acc_block else float("nan"),
            "n_blocks": len(s.blocks),
            "log_evidence": logz, "options": dict(options), "method": method,
            "n_seen": len(terms.triplets), "n_metric": int(terms.metric.sum())}
    return ConfigurationPosterior(ids, s.X, groups, part, pr, method, terms, options, diag, q)
