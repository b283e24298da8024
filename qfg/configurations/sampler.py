"""The tempered sequential Monte Carlo sampler of configuration inference
(:mod:`qfg.configurations`): particles from the world prior, the likelihood tempered in by stages
chosen for the effective sample size, each stage followed by a resampling per population and the
Metropolis moves (one landmark at a time, a similarity transform of the whole configuration, and
of blocks of landmarks: :func:`_landmark_blocks`).
"""

from __future__ import annotations

import numpy as np

from .evidence import _lookup_of, _term_loglik

__all__: list[str] = []


def _landmark_blocks(ijk, n) -> list:
    """Blocks of landmarks the sampler moves as one (``_Sampler.move_blocks``), from the seen
    triplets' landmark indices ``ijk`` (T, 3) of ``n`` landmarks: the connected components of the
    evidence (landmarks linked by a common seen triplet) and its rigid clusters (seen triplets
    linked when they share two landmarks: a cluster's shape is tied together, its placement
    relative to another cluster only through one shared landmark or none); blocks of fewer than
    two landmarks, or of all of them (the whole-configuration move does that), are left out.

    >>> [b.tolist() for b in _landmark_blocks(np.array([[0, 1, 2], [1, 2, 3], [3, 4, 5]]), 6)]
    [[3, 4, 5], [0, 1, 2, 3]]
    """
    def find(par, i):
        while par[i] != i:
            par[i] = par[par[i]]
            i = par[i]
        return i

    ijk = np.asarray(ijk, dtype=np.intp).reshape(-1, 3)
    blocks = []
    par = list(range(n))
    for t in ijk:
        for x in t[1:]:
            par[find(par, int(x))] = find(par, int(t[0]))
    comp = {}
    for l in {int(x) for x in ijk.ravel()}:
        comp.setdefault(find(par, l), []).append(l)
    blocks += [sorted(c) for c in comp.values()]
    T = len(ijk)
    tp = list(range(T))
    by_pair = {}
    for r, t in enumerate(ijk.tolist()):
        for a, b in ((0, 1), (0, 2), (1, 2)):
            key = (min(t[a], t[b]), max(t[a], t[b]))
            if key in by_pair:
                tp[find(tp, r)] = find(tp, by_pair[key])
            else:
                by_pair[key] = r
    cl = {}
    for r, t in enumerate(ijk.tolist()):
        cl.setdefault(find(tp, r), set()).update(t)
    blocks += [sorted(c) for c in cl.values()]
    out, seen = [], set()
    for b in sorted(blocks, key=lambda b: (len(b), b)):
        key = tuple(b)
        if 2 <= len(b) < n and key not in seen:
            seen.add(key)
            out.append(np.array(b, dtype=np.intp))
    return out


class _Sampler:
    """Tempered SMC over world configurations, stored landmark-major: ``Xt`` (n, P, 2) (gathering
    the landmarks of many triplets is then a copy of whole rows); per-term log-likelihoods ``ll``
    (T, P). Particle p belongs to group p // Pg."""

    def __init__(self, X, terms, part, pr, floor, rng, n_groups, block_moves=True):
        self.Xt = np.ascontiguousarray(np.transpose(X, (1, 0, 2)))
        self.terms, self.part, self.pr = terms, part, pr
        self.floor, self.rng, self.G = floor, rng, n_groups
        self.n, self.P = self.Xt.shape[:2]
        self.Pg = self.P // n_groups
        self.box = np.array([pr.width, pr.height])
        self.of_landmark = [np.flatnonzero(np.any(terms.ijk == l, axis=1)) for l in range(self.n)]
        self._lookup = _lookup_of(part)
        self.ll = self._loglik(np.arange(len(terms.ijk)))
        self.step = np.full(self.n, 0.5)
        self.sim_step = 0.5
        self.blocks = _landmark_blocks(terms.ijk, self.n) if block_moves else []
        self.block_step = np.full(len(self.blocks), 0.5)
        self.block_terms = [np.unique(np.concatenate([self.of_landmark[l] for l in S]))
                            for S in self.blocks]
        self._spread_all = 1.0
        self.acc_block = []
        self.acc_land, self.acc_sim = [], []

    @property
    def X(self):
        """(P, n, 2) positions."""
        return np.transpose(self.Xt, (1, 0, 2))

    # -- likelihood
    def _loglik(self, idx, l=None, prop=None):
        """(len(idx), P) log-likelihood of terms idx; with l, prop: landmark l moved to prop."""
        t = self.terms
        ijk = t.ijk[idx]
        pts = [self.Xt[ijk[:, a]] for a in range(3)]                    # (T, P, 2) each, copies
        if l is not None:
            ls = np.atleast_1d(l)
            props = prop[None] if prop.ndim == 2 else prop                  # (k, P, 2)
            for a in range(3):
                for j, lj in enumerate(ls):
                    hit = ijk[:, a] == lj
                    if hit.any():
                        pts[a][hit] = props[j][None]
        return _term_loglik(t, idx, pts, self._lookup)

    def coef(self, beta):
        k = self.terms.kind
        return np.where(k == 0, 1.0, np.where(k == 1, beta, 1.0 - beta))

    def tempered(self):
        """(P,) d log target / d beta."""
        k = self.terms.kind
        return self.ll[k == 1].sum(axis=0) - self.ll[k == 2].sum(axis=0)

    # -- prior
    def _inside(self, pts):
        return np.all((pts >= 0.0) & (pts <= self.box), axis=-1)

    def _min_dist(self, l, prop):
        """(P,) least distance from prop (P, 2) to the other landmarks."""
        if self.n < 2:
            return np.full(self.P, np.inf)
        d = self.Xt - prop[None]
        d2 = np.einsum("npk,npk->np", d, d)
        d2[l] = np.inf
        return np.sqrt(np.min(d2, axis=0))

    def _min_pair(self, Xt):
        """(P,) least pairwise distance within each configuration, Xt (n, P, 2)."""
        out = np.full(Xt.shape[1], np.inf)
        for i in range(Xt.shape[0] - 1):
            d = Xt[i + 1:] - Xt[i][None]
            np.minimum(out, np.min(np.einsum("npk,npk->np", d, d), axis=0), out=out)
        return np.sqrt(out)

    # -- moves
    def _spread(self):
        """(n,) per landmark, the mean within-group standard deviation of its position."""
        Xg = self.Xt.reshape(self.n, self.G, self.Pg, 2)
        return np.sqrt(np.mean(np.var(Xg, axis=2), axis=(1, 2)))

    def move_landmarks(self, beta):
        coef = self.coef(beta)
        spread = self._spread()
        rng = self.rng
        acc = np.zeros(self.n)
        for l in rng.permutation(self.n):
            sd = max(self.step[l] * spread[l], 1e-6)
            prop = self.Xt[l] + sd * rng.standard_normal((self.P, 2))
            ok = self._inside(prop)
            if self.pr.d_min > 0:
                ok &= self._min_dist(l, prop) >= self.pr.d_min
            idx = self.of_landmark[l]
            logu = np.log(rng.random(self.P))
            if idx.size:
                new = self._loglik(idx, l, prop)
                dlog = coef[idx] @ (new - self.ll[idx])
            else:
                new, dlog = None, np.zeros(self.P)
            a = ok & (logu < dlog)
            self.Xt[l, a] = prop[a]
            if new is not None and a.any():
                self.ll[idx] = np.where(a[None, :], new, self.ll[idx])
            acc[l] = a.mean()
        self.acc_land.append(float(acc.mean()))
        return acc

    def move_similarity(self):
        rng, P, n = self.rng, self.P, self.n
        c = self.Xt.mean(axis=0, keepdims=True)
        th = self.sim_step * 0.3 * rng.standard_normal(P)
        ls = self.sim_step * 0.5 / max(n, 1) * rng.standard_normal(P)
        tr = self.sim_step * 0.3 * rng.standard_normal((1, P, 2))
        s = np.exp(ls)
        cs, sn = np.cos(th) * s, np.sin(th) * s
        d = self.Xt - c
        Y = np.stack([cs * d[..., 0] - sn * d[..., 1], sn * d[..., 0] + cs * d[..., 1]],
                     axis=-1) + c + tr
        ok = np.all(self._inside(Y), axis=0)
        shrink = ok & (s < 1)
        if self.pr.d_min > 0 and shrink.any():
            ok[shrink] = self._min_pair(Y[:, shrink]) >= self.pr.d_min
        # likelihoods are invariant; the box prior is flat: the Jacobian decides, s^(2(n-1)) (the
        # centroid is translated, the n - 1 independent offsets from it rotated and scaled)
        a = ok & (np.log(rng.random(P)) < 2 * (n - 1) * ls)
        self.Xt[:, a] = Y[:, a]
        self.acc_sim.append(float(a.mean()))
        return float(a.mean())

    def move_blocks(self, beta):
        """A random similarity transform of one block of landmarks at a time (about the block's
        centroid; the others stay), accepted by Metropolis on the likelihood of the triplets that
        touch the block and the prior. A block whose triplets all lie inside it (a connected
        component of the evidence) keeps its likelihood: the move carries it across the
        placements relative to the rest that no evidence constrains; a rigid cluster tied to
        the rest by one or two landmarks moves about them where the evidence allows."""
        if not self.blocks:
            return np.zeros(0)
        coef = self.coef(beta)
        rng, P = self.rng, self.P
        acc = np.zeros(len(self.blocks))
        for b in rng.permutation(len(self.blocks)):
            S = self.blocks[b]
            k = S.size
            st = self.block_step[b]
            Xs = self.Xt[S]                                                   # (k, P, 2)
            c = Xs.mean(axis=0, keepdims=True)
            th = st * 0.3 * rng.standard_normal(P)
            ls = st * 0.5 / k * rng.standard_normal(P)
            tr = st * 0.3 * self._spread_all * rng.standard_normal((1, P, 2))
            sc = np.exp(ls)
            cs, sn = np.cos(th) * sc, np.sin(th) * sc
            d = Xs - c
            Y = np.stack([cs * d[..., 0] - sn * d[..., 1], sn * d[..., 0] + cs * d[..., 1]],
                         axis=-1) + c + tr
            ok = np.all(self._inside(Y), axis=0)
            if self.pr.d_min > 0:
                rest = np.setdiff1d(np.arange(self.n), S)
                md = np.full(P, np.inf)
                for j in range(k):
                    if rest.size:
                        dd = self.Xt[rest] - Y[j][None]
                        np.minimum(md, np.min(np.einsum("npk,npk->np", dd, dd), axis=0), out=md)
                if k > 1:
                    np.minimum(md, self._min_pair(Y) ** 2, out=md)
                ok &= np.sqrt(md) >= self.pr.d_min
            idx = self.block_terms[b]
            if idx.size:
                new = self._loglik(idx, S, Y)
                dlog = coef[idx] @ (new - self.ll[idx])
            else:
                new, dlog = None, np.zeros(P)
            a = ok & (np.log(rng.random(P)) < dlog + 2 * (k - 1) * ls)
            self.Xt[np.ix_(S, a)] = Y[:, a]
            if new is not None and a.any():
                self.ll[idx] = np.where(a[None, :], new, self.ll[idx])
            acc[b] = a.mean()
        self.acc_block.append(float(acc.mean()))
        return acc

    def sweep(self, beta, n_sweeps):
        accs, sims, blks = [], [], []
        for _ in range(n_sweeps):
            accs.append(self.move_landmarks(beta))
            if self.blocks:
                self._spread_all = float(np.mean(self._spread()))
                blks.append(self.move_blocks(beta))
            sims.append(self.move_similarity())
        if blks:
            self.block_step *= np.exp(np.clip(np.mean(blks, axis=0) - 0.3, -0.3, 0.3) * 2)
            self.block_step = np.clip(self.block_step, 1e-3, 3.0)
        acc = np.mean(accs, axis=0)
        # steps adapted toward an acceptance of about 0.3 (fixed within a stage)
        self.step *= np.exp(np.clip(acc - 0.3, -0.3, 0.3) * 2)
        self.step = np.clip(self.step, 1e-4, 3.0)
        self.sim_step = float(np.clip(self.sim_step * np.exp(2 * (np.mean(sims) - 0.3)),
                                      1e-3, 3.0))

    # -- resampling
    def resample(self, logw):
        """Systematic resampling within each group; returns the per-group log mean weight."""
        G, Pg = self.G, self.Pg
        lw = logw.reshape(G, Pg)
        mx = lw.max(axis=1, keepdims=True)
        w = np.exp(lw - mx)
        tot = w.sum(axis=1, keepdims=True)
        logz = (np.log(tot[:, 0] / Pg) + mx[:, 0])
        cdf = np.cumsum(w / tot, axis=1)
        cdf[:, -1] = 1.0
        u = (self.rng.random((G, 1)) + np.arange(Pg)[None, :]) / Pg
        idx = np.stack([np.searchsorted(cdf[g], u[g]) for g in range(G)])
        idx = np.minimum(idx, Pg - 1) + (np.arange(G) * Pg)[:, None]
        idx = idx.reshape(-1)
        self.Xt = self.Xt[:, idx]
        self.ll = self.ll[:, idx]
        return logz

    def ess_fraction(self, logw):
        lw = logw.reshape(self.G, self.Pg)
        w = np.exp(lw - lw.max(axis=1, keepdims=True))
        w /= w.sum(axis=1, keepdims=True)
        return float(np.mean(1.0 / np.sum(w * w, axis=1)) / self.Pg)

    def run(self, target_ess, n_sweeps, max_stages=1000):
        betas, esss, logz = [0.0], [], np.zeros(self.G)
        beta = 0.0
        D = self.tempered()
        if not np.any(self.terms.kind != 0):
            return betas, esss, logz
        while beta < 1.0 and len(betas) <= max_stages:
            D = self.tempered()
            if self.ess_fraction((1.0 - beta) * D) >= target_ess:
                nb = 1.0
            else:
                lo, hi = beta, 1.0
                for _ in range(50):
                    mid = 0.5 * (lo + hi)
                    if self.ess_fraction((mid - beta) * D) >= target_ess:
                        lo = mid
                    else:
                        hi = mid
                nb = max(lo, beta + 1e-6)
            esss.append(self.ess_fraction((nb - beta) * D))
            logz += self.resample((nb - beta) * D)
            beta = nb
            betas.append(beta)
            self.sweep(beta, n_sweeps)
        return betas, esss, logz
