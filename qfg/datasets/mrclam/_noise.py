"""The noise of MRCLAM's measurements and odometry, measured against motion capture (dataset 6).

:func:`measure_noise` compares what the robots measured with what their motion-capture poses
(``RobotN_Groundtruth``) and the landmark ground truth imply:

* clock offsets: the motion-capture time that best explains the bearings (``measurement_offset``:
  measurement stamp + offset = capture time) and the odometry (``odometry_offset``: odometry
  stamp + offset = capture time), each by a grid search minimizing a robust spread;
* bearing noise: measured bearing minus ``bearing(capture pose, landmark)``;
* odometry direction of travel between the views of the histories (per step and per pass) against
  the captured one, and the odometry's travelled distance (and the ratio of consecutive step
  lengths) against the captured one;
* how bearing errors persist in time: the correlation of one landmark's within-image residuals
  seen by one robot at two times, by their separation (:data:`LAG_BINS`), against landmark
  positions refitted from the bearings and capture poses (so that an error of the landmarks'
  ground truth, a few centimetres, does not pass for noise that persists).

Statistics are robust (median, 1.4826 x median absolute deviation): the data have outliers
(misread barcodes, capture drop-outs) that would dominate a plain standard deviation, which is
also reported.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np
from scipy.stats import spearmanr

from ..._validate import as_float_array
from ...geometry import bearing, motion_heading, wrap_angle
from ...nonlinear import intersect_rays
from ._constants import DEFAULT_MAX_GAP, DEFAULT_MIN_INTERVAL, DEFAULT_MIN_TRAVEL, DEFAULT_ODOMETRY_LEAD
from ._data import MRCLAMDataset, RobotData
from ._histories import triplet_segments, view_poses

_MAD = 1.4826  # MAD -> standard deviation for a normal distribution
_Z90 = 1.6448536  # 90th percentile of |z| for a standard normal z

#: Time separations (seconds, [lo, hi)) at which the persistence of bearing errors is measured.
LAG_BINS = ((0.5, 3.0), (3.0, 10.0), (10.0, 30.0), (30.0, 60.0), (60.0, 120.0), (300.0, 600.0))
#: Residuals beyond this (radians) are gross errors (misread barcodes), left out of the
#: correlations, which a few of them would otherwise set.
LAG_GROSS = np.deg2rad(3.0)


@dataclass(frozen=True)
class RobustStats:
    """Summary of a sample x (n,): ``n``, ``median``, ``robust_std`` (1.4826 x MAD about the
    median), ``std``, ``p50_abs`` and ``p90_abs`` (percentiles of |x|). All zero for n = 0.
    ``sigma90``: the standard deviation of the zero-mean normal with the same 90th percentile of
    |x| (``p90_abs / 1.6449``): a scale that, unlike ``robust_std``, sees the tails and the bias,
    and unlike ``std`` is not set by a few gross outliers.

    >>> s = RobustStats.of([0.0, 1.0, -1.0, 2.0, 100.0])
    >>> (s.n, s.median, round(s.robust_std, 4), s.p50_abs)
    (5, 1.0, 1.4826, 1.0)
    """

    n: int
    median: float
    robust_std: float
    std: float
    p50_abs: float
    p90_abs: float

    @property
    def sigma90(self) -> float:
        return self.p90_abs / _Z90

    @classmethod
    def of(cls, x) -> RobustStats:
        x = np.asarray(x, dtype=float).ravel()
        if x.size == 0:
            return cls(0, 0.0, 0.0, 0.0, 0.0, 0.0)
        med = float(np.median(x))
        a = np.abs(x)
        return cls(int(x.size), med, float(_MAD * np.median(np.abs(x - med))), float(np.std(x)),
                   float(np.median(a)), float(np.percentile(a, 90)))


def _robust_spread(x: np.ndarray) -> float:
    return float(_MAD * np.median(np.abs(x - np.median(x)))) if x.size else np.inf


@dataclass(frozen=True)
class NoiseMeasurement:
    """What :func:`measure_noise` measured on one dataset. Angles in radians, times in seconds.

    Attributes:
        dataset: the dataset's name; ``robots``: the robots used (those with ground truth).
        measurement_offset: capture time - measurement stamp that minimizes the bearing residuals'
            robust spread over ``offsets``; ``odometry_offset``: capture time - odometry stamp that
            minimizes the robust spread of the odometry's heading change over ``window`` seconds
            against the capture's. ``odometry_lead``: ``odometry_offset - measurement_offset``, the
            time to add to odometry stamps to put them on the measurements' clock.
        bearing: measured minus captured bearing, every landmark row of a covered view.
        bearing_within_view: the same residuals minus their view's mean (views with >= 2
            landmarks), scaled by sqrt(k / (k - 1)) for a view of k landmarks: the noise that is
            not common to the image (heading or time errors are).
        bearing_per_robot: ((robot, RobustStats), ...).
        heading_step: odometry minus captured direction of travel between consecutive kept views
            of the default histories (each pair of views once).
        heading_pass: the same from the first to the last view of each history (each pass once).
        distance_step: log(odometry distance / captured distance) per step (steps the capture
            moved at least ``min_distance``); ``distance_pass``: the same from first to last view.
        distance_ratio: log of the odometry's ratio of consecutive step lengths over the
            captured ratio.
        turn_window: odometry minus captured heading change over ``window`` s (at the offset).
        grouping: the history options the steps come from.
        landmark_shift: (L,) distance (m) from each landmark's ground truth to its position
            refitted from every robot's bearings and capture poses (NaN: too few rays).
        bearing_lag_correlation: ((lo, hi, n, pearson, spearman), ...) per :data:`LAG_BINS`:
            the correlation of one landmark's within-view residuals (against the refitted
            positions; gross errors beyond :data:`LAG_GROSS` left out) seen by one robot at a
            time t and at the first time in [t + lo, t + hi). Under the solvers' model (each
            view's errors independent) every value is 0.
    """

    dataset: str
    robots: tuple
    measurement_offset: float
    odometry_offset: float
    odometry_lead: float
    bearing: RobustStats
    bearing_within_view: RobustStats
    bearing_per_robot: tuple
    heading_step: RobustStats
    heading_pass: RobustStats
    distance_step: RobustStats
    distance_pass: RobustStats
    distance_ratio: RobustStats
    turn_window: RobustStats
    window: float
    grouping: tuple
    landmark_shift: tuple = ()
    bearing_lag_correlation: tuple = ()

    def as_dict(self) -> dict:
        out = {}
        for f in fields(self):
            v = getattr(self, f.name)
            out[f.name] = (v.__dict__ if isinstance(v, RobustStats) else
                           [(r, s.__dict__) for r, s in v] if f.name == "bearing_per_robot" else v)
        return out


def _dist(P, i, j):
    return np.hypot(*(P[j, :2] - P[i, :2]).T)


def landmark_rows(dataset: MRCLAMDataset, rd: RobotData):
    """(times, bearings, landmark xy, view index, landmark column) of every landmark
    observation of ``rd``."""
    v, col = np.nonzero(rd.visible)
    return rd.view_times[v], rd.view_bearings[v, col], dataset.landmark_xy[col], v, col


def _minus_view_mean(r, v, n_views):
    """Residuals ``r`` (rows of views ``v``) minus their view's mean, and each row's number of
    rows in its view (the mean on the line, not the circle: residuals are a few degrees)."""
    k = np.bincount(v, minlength=n_views)
    mean = np.bincount(v, weights=r, minlength=n_views) / np.maximum(k, 1)
    return r - mean[v], k[v]


def truth_bearing_residuals(rd, t, phi, lxy, offset):
    """Measured bearings ``phi`` (rad) of the landmarks at ``lxy`` (n, 2) minus those seen from
    robot ``rd``'s motion-capture pose at times ``t + offset`` (s), wrapped to [-pi, pi); and
    the mask of times the motion capture covers."""
    P, ok = rd.groundtruth_poses(t + offset)
    return wrap_angle(phi - bearing(P, lxy)), ok


def _odometry_heading(o, t):
    """Integrated odometry heading (unwrapped, from 0 at the first record) at times ``t``."""
    th = np.concatenate([[0.0], np.cumsum(o.omega[:-1] * np.diff(o.time))])
    k = np.clip(np.searchsorted(o.time, t, side="right") - 1, 0, o.time.size - 1)
    return th[k] + o.omega[k] * (t - o.time[k])


def _turn_errors(rd, offset, window, step):
    """Odometry minus captured heading change over ``window`` s, at sample times every ``step`` s
    (capture time = odometry stamp + offset)."""
    o, gt = rd.odometry, rd.groundtruth
    lo = max(o.time[0] + offset, gt[0, 0])
    hi = min(o.time[-1] + offset, gt[-1, 0]) - window
    if hi <= lo:
        return np.zeros(0)
    T = np.arange(lo, hi, step)
    _, ok0 = rd.groundtruth_poses(T)
    _, ok1 = rd.groundtruth_poses(T + window)
    T = T[ok0 & ok1]
    th = np.unwrap(gt[:, 3])
    d_gt = np.interp(T + window, gt[:, 0], th) - np.interp(T, gt[:, 0], th)
    d_odo = _odometry_heading(o, T + window - offset) - _odometry_heading(o, T - offset)
    return d_odo - d_gt


def refit_landmarks(dataset, robots, rows, offset, sigma):
    """Each landmark's position by :func:`qfg.nonlinear.intersect_rays` over every robot's rays
    (capture pose at the measurement's time + ``offset``, measured bearing); (L, 2), NaN rows
    for a landmark with fewer than 10 rays or no intersection."""
    O, A, C = [], [], []
    for n in robots:
        t, phi, _, _, col = rows[n]
        P, ok = dataset.robots[n].groundtruth_poses(t + offset)
        O.append(P[ok, :2])
        A.append(P[ok, 2] + phi[ok])
        C.append(col[ok])
    O, A, C = np.concatenate(O), np.concatenate(A), np.concatenate(C)
    out = np.full((len(dataset.landmark_ids), 2), np.nan)
    for j in range(out.shape[0]):
        s = C == j
        if s.sum() >= 10:
            p, ok, _ = intersect_rays(O[s], A[s], sigma)
            if ok:
                out[j] = p
    return out


def lag_pairs(times, values, lo: float, hi: float):
    """Pairs of one series at separations in [lo, hi): for each sample i of ``times`` (n,)
    (sorted), the first later sample j with ``lo <= times[j] - times[i] < hi``. Returns the
    two (k,) arrays (values[i], values[j]).

    >>> a, b = lag_pairs(np.array([0.0, 1.0, 2.5, 7.0]), np.arange(4.0), 1.0, 3.0)
    >>> a.tolist(), b.tolist()
    ([0.0, 1.0], [1.0, 2.0])
    """
    t = np.asarray(times, float)
    j = np.searchsorted(t, t + lo, side="left")
    has = j < np.searchsorted(t, t + hi, side="left")
    return values[has], values[j[has]]


def _lag_correlations(dataset, robots, rows, offset, points):
    """``NoiseMeasurement.bearing_lag_correlation`` against landmark positions ``points``."""
    pairs = {b: ([], []) for b in LAG_BINS}
    for n in robots:
        rd = dataset.robots[n]
        t, phi, _, v, col = rows[n]
        good = np.isfinite(points[col, 0])
        r, ok = truth_bearing_residuals(rd, t, phi, np.where(good[:, None], points[col], 0.0), offset)
        ok &= good
        t, v, col = t[ok], v[ok], col[ok]
        w, k = _minus_view_mean(r[ok], v, rd.n_views)
        keep = (k >= 2) & (np.abs(w) < LAG_GROSS)
        for lm in np.unique(col[keep]):
            s = keep & (col == lm)
            for b in LAG_BINS:
                x, y = lag_pairs(t[s], w[s], *b)
                pairs[b][0].append(x)
                pairs[b][1].append(y)
    out = []
    for (lo, hi), (xs, ys) in pairs.items():
        x = np.concatenate(xs) if xs else np.zeros(0)
        y = np.concatenate(ys) if ys else np.zeros(0)
        if x.size >= 3 and np.std(x) > 0 and np.std(y) > 0:
            out.append((lo, hi, int(x.size), float(np.corrcoef(x, y)[0, 1]),
                        float(spearmanr(x, y)[0])))
        else:
            out.append((lo, hi, int(x.size), float("nan"), float("nan")))
    return tuple(out)


def measure_noise(dataset: MRCLAMDataset, *, offsets=None, window: float = 1.0,
                  min_travel: float = DEFAULT_MIN_TRAVEL, max_gap: float = DEFAULT_MAX_GAP,
                  min_interval: float = DEFAULT_MIN_INTERVAL, min_distance: float = 0.05,
                  odometry_lead: float = DEFAULT_ODOMETRY_LEAD) -> NoiseMeasurement:
    """Measure bearing, odometry heading and distance noise and the clock offsets of a dataset
    against its robots' motion capture. See :class:`NoiseMeasurement` for what is measured.

    ``offsets`` (default -0.5..0.5 s in 5 ms steps): the grid searched for both clock offsets.
    ``window``: seconds over which odometry and capture heading changes are compared for the
    odometry offset. ``min_travel``, ``max_gap``, ``min_interval``: the history grouping
    (:func:`triplet_segments`) whose steps are measured, with the odometry read ``odometry_lead``
    seconds before each view (as the histories do), so the heading and distance noise is what a
    solver receives.

    ValueError naming ``dataset`` when no robot has ground truth.
    """
    grid = (np.round(np.arange(-0.5, 0.5 + 1e-9, 0.005), 6) if offsets is None
            else as_float_array("offsets", offsets, ndim=1))
    robots = [n for n, rd in dataset.robots.items() if rd.groundtruth is not None]
    if not robots:
        raise ValueError(f"dataset: {dataset.name} has no robot ground truth (RobotN_Groundtruth)")
    rows = {n: landmark_rows(dataset, dataset.robots[n]) for n in robots}

    def bearing_spread(off):
        res = [r[ok] for n in robots
               for r, ok in [truth_bearing_residuals(dataset.robots[n], *rows[n][:3], off)]]
        return _robust_spread(np.concatenate(res))

    m_off = float(grid[int(np.argmin([bearing_spread(x) for x in grid]))])
    with_odo = [n for n in robots if dataset.robots[n].odometry is not None]

    def turn_spread(off):
        return _robust_spread(np.concatenate(
            [_turn_errors(dataset.robots[n], off, window, 0.25) for n in with_odo]))

    o_off = float(grid[int(np.argmin([turn_spread(x) for x in grid]))]) if with_odo else 0.0
    turn = (np.concatenate([_turn_errors(dataset.robots[n], o_off, window, 0.25) for n in with_odo])
            if with_odo else np.zeros(0))

    b_all, b_within, per_robot = [], [], []
    h_step, h_pass, d_step, d_pass, d_ratio = [], [], [], [], []
    for n in robots:
        rd = dataset.robots[n]
        t, phi, lxy, v, _ = rows[n]
        r, ok = truth_bearing_residuals(rd, t, phi, lxy, m_off)
        r, v = r[ok], v[ok]
        b_all.append(r)
        per_robot.append((n, RobustStats.of(r)))
        w, k = _minus_view_mean(r, v, rd.n_views)
        b_within.append((w * np.sqrt(k / np.maximum(k - 1, 1)))[k >= 2])
        if rd.odometry is None:
            continue
        poses, _ = view_poses(rd, odometry_lead)
        gt, gt_ok = rd.groundtruth_poses(rd.view_times + m_off)
        segs = triplet_segments(dataset, n, min_travel=min_travel, max_gap=max_gap,
                                min_interval=min_interval, odometry_lead=odometry_lead)
        steps = {(int(a), int(b)) for s in segs for a, b in zip(s.view_index[:-1], s.view_index[1:],
                                                                 strict=True)}
        passes = {(int(s.view_index[0]), int(s.view_index[-1])) for s in segs}
        triples = {tuple(int(x) for x in s.view_index[j:j + 3]) for s in segs
                   for j in range(s.view_index.size - 2)}
        for pairs, h_out, d_out in ((steps, h_step, d_step), (passes, h_pass, d_pass)):
            if not pairs:
                continue
            a, b = np.array(sorted(pairs)).T
            good = gt_ok[a] & gt_ok[b]
            a, b = a[good], b[good]
            h_out.append(wrap_angle(motion_heading(poses[a], poses[b, :2])
                                    - motion_heading(gt[a], gt[b, :2])))
            do, dg = _dist(poses, a, b), _dist(gt, a, b)
            keep = (dg >= min_distance) & (do > 0)
            d_out.append(np.log(do[keep] / dg[keep]))
        if triples:
            a, b, c = np.array(sorted(triples)).T
            good = gt_ok[a] & gt_ok[b] & gt_ok[c]
            a, b, c = a[good], b[good], c[good]
            do1, do2 = _dist(poses, a, b), _dist(poses, b, c)
            dg1, dg2 = _dist(gt, a, b), _dist(gt, b, c)
            keep = (np.minimum(dg1, dg2) >= min_distance) & (np.minimum(do1, do2) > 0)
            d_ratio.append(np.log(do2[keep] / do1[keep]) - np.log(dg2[keep] / dg1[keep]))

    def cat(xs):
        return np.concatenate(xs) if xs else np.zeros(0)

    refit = refit_landmarks(dataset, robots, rows, m_off, RobustStats.of(cat(b_all)).sigma90)
    return NoiseMeasurement(
        dataset=dataset.name, robots=tuple(robots), measurement_offset=m_off,
        odometry_offset=o_off, odometry_lead=o_off - m_off, bearing=RobustStats.of(cat(b_all)),
        bearing_within_view=RobustStats.of(cat(b_within)), bearing_per_robot=tuple(per_robot),
        heading_step=RobustStats.of(cat(h_step)), heading_pass=RobustStats.of(cat(h_pass)),
        distance_step=RobustStats.of(cat(d_step)), distance_pass=RobustStats.of(cat(d_pass)),
        distance_ratio=RobustStats.of(cat(d_ratio)),
        turn_window=RobustStats.of(turn), window=float(window),
        grouping=(("min_travel", min_travel), ("max_gap", max_gap), ("min_interval", min_interval),
                  ("odometry_lead", odometry_lead)),
        landmark_shift=tuple(float(x) for x in np.hypot(*(refit - dataset.landmark_xy).T)),
        bearing_lag_correlation=_lag_correlations(dataset, robots, rows, m_off, refit))


def noise_table(m: NoiseMeasurement) -> str:
    """A markdown table of a :class:`NoiseMeasurement` (angles in degrees, log ratios in %)."""
    deg = np.degrees
    head = ["| quantity | n | median | robust std | std | median abs | 90th pct abs | sigma90 |",
            "|---|---|---|---|---|---|---|---|"]

    def row(name, s, scale, unit):
        return (f"| {name} | {s.n} | {scale(s.median):.3f}{unit} | {scale(s.robust_std):.3f}{unit} | "
                f"{scale(s.std):.3f}{unit} | {scale(s.p50_abs):.3f}{unit} | "
                f"{scale(s.p90_abs):.3f}{unit} | {scale(s.sigma90):.3f}{unit} |")

    pct = lambda x: 100 * x  # noqa: E731 - log ratio ~ relative error
    lines = [f"{m.dataset} (robots {', '.join(map(str, m.robots))}): capture time = measurement "
             f"stamp {m.measurement_offset:+.3f} s = odometry stamp {m.odometry_offset:+.3f} s "
             f"(measurement clock = odometry stamp {m.odometry_lead:+.3f} s); steps from "
             f"histories with {dict(m.grouping)}", ""] + head
    lines.append(row("bearing (measured - captured)", m.bearing, deg, " deg"))
    lines.append(row("bearing, within one view", m.bearing_within_view, deg, " deg"))
    for n, s in m.bearing_per_robot:
        lines.append(row(f"bearing, robot {n}", s, deg, " deg"))
    lines.append(row(f"odometry turn over {m.window:g} s", m.turn_window, deg, " deg"))
    lines.append(row("odometry direction of travel, per step", m.heading_step, deg, " deg"))
    lines.append(row("odometry direction of travel, per pass", m.heading_pass, deg, " deg"))
    lines.append(row("odometry step length, log ratio", m.distance_step, pct, " %"))
    lines.append(row("odometry pass length, log ratio", m.distance_pass, pct, " %"))
    lines.append(row("ratio of consecutive step lengths, log ratio", m.distance_ratio, pct, " %"))
    if m.bearing_lag_correlation:
        shift = np.array(m.landmark_shift, float)
        lines += ["", "Persistence of bearing errors: correlation of one landmark's within-view "
                  "residuals seen by one robot at two times (landmarks refitted from the bearings: "
                  f"{100 * np.nanmedian(shift):.1f} cm from their ground truth at the median, "
                  f"{100 * np.nanmax(shift):.1f} cm at most)", "",
                  "| separation | pairs | Pearson | Spearman |", "|---|---|---|---|"]
        lines += [f"| {lo:g}-{hi:g} s | {n} | {p:+.3f} | {r:+.3f} |"
                  for lo, hi, n, p, r in m.bearing_lag_correlation]
    return "\n".join(lines)
