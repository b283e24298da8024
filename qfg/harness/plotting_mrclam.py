"""Figures of MRCLAM data: the landmarks and one robot's path in the world frame; a joint map
or a configuration map against the ground truth.

Plotting is the end of the data flow: this module imports ``qfg.datasets.mrclam``; nothing in the
data path imports it.
"""

from __future__ import annotations

import textwrap

import matplotlib.pyplot as plt
import numpy as np

from qfg.datasets import mrclam as _mrclam

__all__ = ["draw_dataset", "dataset_figure", "reliability_figure", "curve_figure",
           "maps_figure", "joint_map_figure", "configuration_map_figure"]


def draw_dataset(dataset, robot, ax=None, *, history=None, time_range=None,
                 max_residual: float = 0.15):
    """Landmarks (numbered by subject) and robot ``robot``'s path in the world frame.

    Robot ground truth is absent from the data, so the path is the odometry dead-reckoned from
    the first good landmark fix in ``time_range`` (:func:`qfg.datasets.mrclam.anchored_dead_reckoning`),
    drawn with the landmark fixes (poses from range and bearing to known landmarks, rms residual
    at most ``max_residual`` m) so that its drift shows; the figure says so. A robot without
    odometry gets the fixes alone. ``time_range``: (start, end) seconds from the robot's first
    measurement (default: all). ``history``: a :class:`qfg.simulation.TripletHistory` of this
    robot whose views are marked (dead-reckoned from the fix nearest its first view, or at the
    nearest fixes without odometry), with lines of sight to its landmarks.
    """
    rd = dataset.robot(robot)
    if ax is None:
        _, ax = plt.subplots(figsize=(7, 7))
    t0 = float(rd.time[0]) if rd.time.size else 0.0
    lo, hi = (-np.inf, np.inf) if time_range is None else (t0 + time_range[0], t0 + time_range[1])
    fixes = _mrclam.landmark_fixes(dataset, robot, min_landmarks=3)
    good = (fixes.residual <= max_residual) & (fixes.times >= lo) & (fixes.times <= hi)
    span = "" if time_range is None else f", t in [{time_range[0]:g}, {time_range[1]:g}] s"
    if rd.odometry is not None:
        o = rd.odometry
        keep = (o.time >= lo) & (o.time <= hi)
        anchor = fixes.times[good][0] if good.any() else None
        path, t_anchor = _mrclam.anchored_dead_reckoning(dataset, robot, o.time[keep],
                                                         anchor_time=anchor,
                                                         max_residual=max_residual)
        ax.plot(path[:, 0], path[:, 1], "-", color="tab:red", lw=0.7, alpha=0.8,
                label="path: dead-reckoned odometry")
        note = (f"robot path dead-reckoned from odometry (no robot ground truth in the data), "
                f"placed at a landmark fix (t = {t_anchor - t0:.1f} s)")
    else:
        path = None
        note = "robot without odometry: landmark fixes only (no robot ground truth in the data)"
    ax.plot(fixes.poses[good, 0], fixes.poses[good, 1], ".", color="tab:orange", ms=3,
            label=f"landmark fixes ({int(good.sum())}, range+bearing)")
    L = dataset.landmark_xy
    ax.plot(L[:, 0], L[:, 1], "o", color="tab:blue", ms=8, label="landmarks (ground truth)")
    for lid, (x, y) in zip(dataset.landmark_ids, L, strict=True):
        ax.annotate(str(int(lid)), (x, y), xytext=(5, 5), textcoords="offset points",
                    color="tab:blue", fontsize=8)
    if history is not None:
        times = np.asarray(history.views, dtype=float)
        if path is not None:
            P, _ = _mrclam.anchored_dead_reckoning(dataset, robot, times, anchor_time=times[0],
                                                   max_residual=max_residual)
        else:
            P = _nearest_fixes(fixes, times)
        A = dataset.landmark_position(list(history.landmarks))
        for p in P:
            for a in A:
                ax.plot([p[0], a[0]], [p[1], a[1]], ":", color="0.4", lw=0.7)
        ax.plot(P[:, 0], P[:, 1], "k^", ms=6,
                label=f"views of triplet {history.landmarks[0]},{history.landmarks[1]}:"
                      f"{history.landmarks[2]}")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    ax.set_title(f"{dataset.name}, robot {rd.robot}{span}", fontsize=10)
    ax.text(0.0, -0.08, note, transform=ax.transAxes, fontsize=7, va="top", ha="left")
    return ax


def _nearest_fixes(fixes, times):
    k = np.clip(np.searchsorted(fixes.times, times), 0, fixes.times.size - 1)
    return fixes.poses[k]


def dataset_figure(dataset, robot, path, **kw):
    """Write :func:`draw_dataset` to ``path`` (format from its suffix); returns ``path``."""
    fig, ax = plt.subplots(figsize=(9.5, 7))
    draw_dataset(dataset, robot, ax, **kw)
    fig.tight_layout()
    fig.savefig(path, dpi=130, format=str(path).rsplit(".", 1)[-1] if "." in str(path) else "png")
    plt.close(fig)
    return path


def _count_marker_size(count):
    """Marker area (points^2) of a bin holding ``count`` estimates: logarithmic, so that bins of
    10 and of 100 000 estimates are both visible and sizes compare across groups and panels."""
    return 10.0 + 15.0 * np.log10(1.0 + np.asarray(count, dtype=float))


def reliability_figure(groups, *, bins: int = 10, title: str = "reliability"):
    """Calibration of estimates: for each group ``name -> (P (n, m), truths (n,))`` the top-state
    reliability (mean confidence of the most likely state against how often it is the truth) and
    the all-states one (every (estimate, state) probability against its frequency), from
    :func:`qfg.metrics.reliability`; the diagonal is perfect calibration, and the marker area
    grows with the logarithm of the bin's count (a legend shows 10, 100, 1000, 10000). Legends sit
    below the axes, where they cover no point. Returns the figure."""
    from qfg import metrics

    # constrained layout makes room for the legends below the axes
    fig, axes = plt.subplots(1, 2, figsize=(10, 5.6), layout="constrained")
    for name, (P, g) in groups.items():
        r = metrics.reliability(P, g, bins)
        ece = metrics.expected_calibration_error(P, g, bins)
        for ax, conf, acc, cnt in ((axes[0], r.top_confidence, r.top_accuracy, r.top_count),
                                   (axes[1], r.all_confidence, r.all_frequency, r.all_count)):
            ok = cnt > 0
            line, = ax.plot(conf[ok], acc[ok], "-", lw=1, alpha=0.7)
            ax.scatter(conf[ok], acc[ok], s=_count_marker_size(cnt[ok]), color=line.get_color(),
                       label=f"{name} (n = {len(g)}, ECE {ece:.2f})" if ax is axes[0] else name,
                       clip_on=False, zorder=3)
    for ax, lab in ((axes[0], "most likely state"), (axes[1], "every state")):
        ax.plot([0, 1], [0, 1], "k:", lw=1)
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_aspect("equal")
        ax.set_xlabel("predicted probability (bin mean)")
        ax.set_ylabel("observed frequency")
        ax.set_title(f"{lab}", fontsize=9)
    axes[0].legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12), frameon=False)
    sizes = [10, 100, 1000, 10000]
    handles = [axes[1].scatter([], [], s=_count_marker_size(c), color="0.5") for c in sizes]
    axes[1].legend(handles, [f"{c}" for c in sizes], title="estimates in the bin", ncol=4,
                   fontsize=7, title_fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.12),
                   frameon=False)
    fig.suptitle(title, fontsize=10)
    return fig


def curve_figure(recs):
    """Scores of seen triplets (and cameras) against the views kept per pass, with the uniform and
    prior-alone baselines dashed: records of ``qfg.harness.studies.mrclam.views_curve``."""
    fig, axes = plt.subplots(1, 3, figsize=(13, 4))
    keys = (("log_score", "mean log p(truth) (clip 1e-4)"), ("brier", "mean Brier"),
            ("truth_under_1pct", "truth under 1%"))
    series = {}
    for r in recs:
        series.setdefault((r["dataset"], r["mode"], r["kind"]), []).append(r)
    for (ds, mode, kind), rs in series.items():
        rs = sorted(rs, key=lambda r: r["views_median"])
        x = [r["views_median"] for r in rs]
        for ax, (k, lab) in zip(axes, keys, strict=True):
            line, = ax.plot(x, [r[k] for r in rs], "o-", label=f"{ds} {mode} {kind}")
            for pre, ls in (("uniform_", "--"), ("prior_", ":")):
                ax.plot(x, [r[pre + k] for r in rs], ls, color=line.get_color(), lw=0.8)
            ax.set_title(lab, fontsize=9)
            ax.set_xlabel("median views per history")
    axes[0].legend(fontsize=7)
    fig.suptitle("scores vs views per pass (dashed: uniform, dotted: prior alone)", fontsize=10)
    fig.tight_layout()
    return fig


def maps_figure(rows, *, title: str = "every map of qfg mrclam on MRCLAM datasets 1-6"):
    """The map comparison (rows of ``qfg.harness.studies.mrclam.compare``: dataset, map, kind,
    log_score, truth_under_1pct, uniform_log_score, prior_log_score): one panel per kind (seen,
    unseen, cameras where scored), a bar per (dataset, map) from the prior alone's mean log
    p(truth) (a black segment over each dataset's group) to the map's (clip 1e-4): up is a gain
    over the prior, down a loss; hatched where another map answered (the joint map's fallback);
    uniform (log 1/20) dashed. Returns the figure."""
    kinds = [k for k in ("seen", "propagated", "camera") if any(r["kind"] == k for r in rows)]
    maps = list(dict.fromkeys(r["map"] for r in rows))
    datasets = list(dict.fromkeys(str(r["dataset"]) for r in rows))
    by = {(str(r["dataset"]), r["kind"], r["map"]): r for r in rows}
    colors = plt.get_cmap("tab10")(np.arange(len(maps)) % 10)
    fig, axes = plt.subplots(len(kinds), 1, figsize=(11, 3.3 * len(kinds)), squeeze=False,
                             layout="constrained",
                             gridspec_kw={"height_ratios": [1.0 if k != "camera" else 0.7
                                                            for k in kinds]})
    width = 0.8 / max(len(maps), 1)
    for ax, kind in zip(axes[:, 0], kinds, strict=True):
        shown = [d for d in datasets if any((d, kind, m) in by for m in maps)]
        for j, m in enumerate(maps):
            for i, d in enumerate(shown):
                r = by.get((d, kind, m))
                if r is None:
                    continue
                fallback = r.get("answered_by", m) not in ("", m)
                base = float(r["prior_log_score"])
                ax.bar(i + (j - (len(maps) - 1) / 2) * width, float(r["log_score"]) - base, width,
                       bottom=base, color=colors[j], hatch="//" if fallback else None,
                       edgecolor="white" if fallback else None, label=m)
        labels = []
        for i, d in enumerate(shown):
            r = next(by[(d, kind, m)] for m in maps if (d, kind, m) in by)
            ax.hlines(float(r["prior_log_score"]), i - 0.45, i + 0.45, color="k", lw=2,
                      label="prior alone")
            rb = r.get("robots", "all")
            labels.append(f"dataset {d}" + ("" if rb in ("", "all") else f"\n(robot {rb})"))
        ax.axhline(float(r["uniform_log_score"]), color="k", ls="--", lw=0.8, label="uniform")
        ax.set_xticks(range(len(shown)), labels)
        ax.set_ylabel("mean log p(truth)")
        ax.set_title({"seen": "seen triplets", "propagated": "unseen triplets",
                      "camera": "camera states (motion capture)"}[kind], fontsize=9)
        ax.grid(axis="y", alpha=0.3)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    keep = {}
    for lab, h in zip(labels, handles, strict=True):
        keep.setdefault(lab, h)   # the first of each: never a hatched fallback bar
    fig.legend(keep.values(), keep.keys(), loc="outside lower center", ncol=min(len(keep), 6),
               fontsize=8, frameon=False)
    fig.suptitle(title + " (bars from the prior alone to the map: up is better; hatched: "
                 "answered by the fallback)", fontsize=10)
    return fig


#: chi-square quantile (2 dof) of a 95 % ellipse
_CHI2_95 = 5.991464547107979


def _nice_factor(x: float) -> float:
    """The smallest of 1, 2, 5, 10, 20, 50, ... at least ``x``."""
    if not np.isfinite(x) or x <= 1:
        return 1.0
    e = 10.0 ** np.floor(np.log10(x))
    return float(next(m * e for m in (1, 2, 5, 10) if m * e >= x))


def _map_size(points) -> tuple:
    """A map figure's size (inches) for ``points`` (n, 2) drawn at equal aspect, with room for
    the legend on the right: 9 inches tall, as wide as their extent asks within 8-15."""
    ext = np.ptp(np.asarray(points, dtype=float), axis=0)
    return float(np.clip(8.5 * ext[0] / max(ext[1], 1e-9) + 4.5, 8.0, 15.0)), 9.0


def _finish_map(fig, ax, title: str, note: str):
    """A map figure's common end: equal axes in metres, the legend on the right, the title and
    the note under the axes."""
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    ax.set_title(title, fontsize=10)
    fig.text(0.02, 0.01, "\n".join(textwrap.wrap(note, 150)), fontsize=7, va="bottom",
             ha="left")
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return fig


def joint_map_figure(geometry: dict, dataset, *, magnify: float | None = None):
    """A joint map (``geometry``: :func:`qfg.harness.studies.mrclam.maps.joint_geometry`)
    against the dataset's ground truth. The map is drawn in the ground truth's frame by the
    landmarks' best similarity (a qualitative map has no scale, position or heading of its
    own). Each landmark's error and 95 % ellipse (its uncertainty relative to the other
    landmarks) are drawn about its true position, magnified ``magnify`` times (default: so
    that they can be seen at the arena's scale); a calibrated map has about 95 % of the true
    positions inside their ellipses: green inside, red outside. Dashed: the ellipses widened
    by the robots' measured scatter about the map (``overdispersion``, no ground truth), when
    it exceeds 1 and the map was not already widened by it. Robot paths: the map's keyframe
    poses, and motion capture (grey) where the data has it. Returns the figure."""
    from matplotlib.patches import Ellipse

    from qfg.joint import aligned_errors
    from qfg.joint.start import apply_similarity

    ids = [int(x) for x in geometry["landmark_ids"]]
    mu = np.asarray(geometry["mean"], dtype=float).reshape(-1, 2)
    cov = np.asarray(geometry["covariance"], dtype=float).reshape(-1, 2, 2)
    truth = dataset.landmark_position(ids)
    ok = np.isfinite(mu).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    span = np.ptp(truth, axis=0)
    aligned = aligned_errors(mu[ok], cov[ok], truth[ok]) if ok.sum() >= 3 else None
    paths = {}
    if aligned is not None:
        paths = {r: apply_similarity(np.asarray(X, dtype=float).reshape(-1, 2), aligned[3])
                 for r, X in sorted(geometry.get("paths", {}).items(), key=lambda kv: int(kv[0]))}
    # the figure's shape from everything drawn: the landmarks and the robots' paths
    fig, ax = plt.subplots(figsize=_map_size(np.concatenate([truth, *paths.values()])))
    ax.plot(truth[:, 0], truth[:, 1], "k+", ms=9, mew=1.5, zorder=4,
            label="landmarks (ground truth)")
    for lid, (x, y) in zip(ids, truth, strict=True):
        ax.annotate(str(lid), (x, y), xytext=(6, 6), textcoords="offset points", fontsize=8,
                    zorder=5)
    note = "fewer than 3 landmarks in the map: nothing to align"
    if aligned is not None:
        err, C, z2, _ = aligned
        sd = np.sqrt(np.linalg.eigvalsh(C)[:, 1])
        k = magnify or _nice_factor(0.04 * float(span.max() or 1.0) / max(float(np.median(
            np.maximum(np.hypot(*err.T), 2.45 * sd))), 1e-12))
        kappa = float(geometry.get("overdispersion", np.nan))
        widen = (np.isfinite(kappa) and kappa > 1
                 and float(geometry.get("covariance_scale", 1.0)) == 1.0)
        inside = z2 <= _CHI2_95
        for c, e, tr, good in zip(C, err, truth[ok], inside, strict=True):
            w, V = np.linalg.eigh(c)
            ang = float(np.degrees(np.arctan2(V[1, 1], V[0, 1])))
            col = "tab:green" if good else "tab:red"
            for f, ls in ((1.0, "-"), (kappa, "--")) if widen else ((1.0, "-"),):
                ax.add_patch(Ellipse(tr + k * e, 2 * k * np.sqrt(_CHI2_95 * f * w[1]),
                                     2 * k * np.sqrt(_CHI2_95 * f * w[0]), angle=ang,
                                     fill=False, color=col, lw=1.1, ls=ls, zorder=3))
            ax.plot([tr[0], tr[0] + k * e[0]], [tr[1], tr[1] + k * e[1]], "-", color=col,
                    lw=1.0, zorder=3)
            ax.plot(*(tr + k * e), "o", color=col, ms=3, zorder=3)
        for r, W in paths.items():
            ax.plot(W[:, 0], W[:, 1], "-", lw=0.6, alpha=0.7, zorder=1, label=f"robot {r}: map")
        note = (f"{int(inside.sum())} of {int(ok.sum())} true landmarks inside their 95 % "
                f"ellipse (a calibrated map: about 95 %)"
                + (f", {int((z2 <= _CHI2_95 * kappa).sum())} inside the dashed one (the "
                   f"covariance x{kappa:.2f}, the robots' scatter about the map)" if widen
                   else "")
                + f"; errors median {100 * np.median(np.hypot(*err.T)):.1f} cm, ellipses' "
                f"major semi-axis median {100 * np.median(np.sqrt(_CHI2_95) * sd):.1f} cm; "
                f"both drawn x{k:g} about the true position")
    gt = False
    for r, rd in sorted(dataset.robots.items()):
        if rd.groundtruth is not None and str(r) in geometry.get("paths", {}):
            g = np.asarray(rd.groundtruth, dtype=float)
            ax.plot(g[:, 1], g[:, 2], "-", color="0.6", lw=0.4, alpha=0.6, zorder=0,
                    label=None if gt else "robots: motion capture")
            gt = True
    scale = float(geometry.get("covariance_scale", 1.0))
    if aligned is not None and scale != 1.0:
        note += f" (the map's covariance already widened x{scale:.2f} by the robots' scatter)"
    lost = [f"{i} ({f})" for i, f, good in zip(ids, geometry["landmark_flags"], ok, strict=True)
            if not good]
    if lost:
        note += "; not in the map (the prior answers): " + ", ".join(lost)
    out = [f"{r} ({f})" for r, f in sorted(geometry.get("robot_flags", {}).items(),
                                           key=lambda kv: int(kv[0]))
           if f not in ("ok", "kinematic")]
    if out:
        note += "; robots left out of the map: " + ", ".join(out)
    ax.plot([], [], "-", color="tab:green", label="error and 95 % ellipse: truth inside")
    ax.plot([], [], "-", color="tab:red", label="truth outside")
    return _finish_map(fig, ax, f"{dataset.name}: the joint map in the ground truth's frame (best "
                       "similarity)", note)


def configuration_map_figure(geometry: dict, dataset):
    """A configuration map (``geometry``: :func:`qfg.harness.studies.mrclam.maps.
    configuration_geometry`) against the dataset's ground truth. Each sampled configuration is
    scaled to the truth's rms radius and turned and moved onto it by least squares, over the
    landmarks of the largest linked group (a configuration's states do not change under
    position, rotation and scale), and its
    landmarks are drawn as dots, one colour per landmark, about their true positions (+): a
    sharp and right map puts each landmark's dots in a tight cloud on its +, a tight cloud off
    its + is a landmark the map places wrongly and confidently. Landmarks outside the largest
    group are drawn aligned the same way (only the prior places them relative to it) and named
    in the note, with each landmark's median distance from its truth. Returns the figure."""
    from qfg.joint.start import apply_similarity, similarity

    ids = [int(x) for x in geometry["landmark_ids"]]
    X = np.asarray(geometry["samples"], dtype=float).reshape(-1, len(ids), 2)
    comp = np.asarray(geometry.get("components", [0] * len(ids)), dtype=int)
    truth = dataset.landmark_position(ids)
    main = comp == np.bincount(comp).argmax()
    fig, ax = plt.subplots(figsize=_map_size(truth))
    note = "fewer than 3 linked landmarks: nothing to align"
    if main.sum() >= 3 and len(X):
        # each sample scaled to the truth's rms radius over the group, then turned and moved
        # onto it by least squares: a least-squares scale regresses toward 0 when the samples
        # scatter (and collapses a sample unlike the truth onto its centroid), which would draw
        # a vague map as a shrunken one
        c = X[:, main].mean(axis=1, keepdims=True)
        rx = np.sqrt(np.mean(np.sum((X[:, main] - c) ** 2, axis=-1), axis=-1))
        T0 = truth[main] - truth[main].mean(axis=0)
        scale = np.sqrt(np.mean(np.sum(T0 ** 2, axis=-1))) / np.maximum(rx, 1e-12)
        Xs = (X - c) * scale[:, None, None]
        _, R, t = similarity(Xs[:, main], truth[main][None], scale=False)
        A = apply_similarity(Xs, (np.ones(len(X)), R, t))                      # (S, L, 2)
        dist = np.median(np.hypot(*(A - truth[None]).transpose(2, 0, 1)), axis=0)  # (L,)
        colours = plt.get_cmap("tab20")(np.arange(len(ids)) % 20)
        for j, lid in enumerate(ids):
            ax.plot(A[:, j, 0], A[:, j, 1], ".", ms=2.5, alpha=0.35, color=colours[j],
                    zorder=2)
            ax.plot([], [], ".", ms=9, color=colours[j],
                    label=f"landmark {lid}: {dist[j]:.2f} m from its truth")
        worst = np.argsort(-dist)[:3]
        span = float(np.ptp(truth, axis=0).max())
        note = (f"{len(X)} sampled configurations, each scaled to the ground truth's size and "
                f"turned and moved onto it over the {int(main.sum())} landmarks of the largest "
                f"linked group; "
                f"median distance of a landmark's dots from its truth: {np.median(dist):.2f} m "
                f"over the landmarks (the arena spans {span:.1f} m), largest "
                + ", ".join(f"{ids[j]} ({dist[j]:.2f} m)" for j in worst))
        if not main.all():
            note += ("; not linked to that group by any seen triplet (the prior alone places "
                     "them): " + ", ".join(str(i) for i, k in zip(ids, main, strict=True)
                                            if not k))
    ax.plot(truth[:, 0], truth[:, 1], "k+", ms=10, mew=1.6, zorder=4,
            label="landmarks (ground truth)")
    for lid, (x, y) in zip(ids, truth, strict=True):
        ax.annotate(str(lid), (x, y), xytext=(6, 6), textcoords="offset points", fontsize=8,
                    zorder=5)
    return _finish_map(fig, ax, f"{dataset.name}: the configuration map's samples in the ground "
                       "truth's frame", note)
