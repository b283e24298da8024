"""Figures: partitions, scenarios and triplets in their AB frame.

Plotting is part of the harness: it imports the library and no library module imports it.
Importing it chooses no matplotlib backend (the ``qfg`` command sets a file backend at its entry
point; a notebook keeps its own). Lengths in the AB frame are in units of ``|AB|``.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import shapely
from matplotlib.patches import PathPatch
from matplotlib.path import Path as MplPath

from qfg import partitions as _partitions

__all__ = ["draw_partition", "draw_scenario", "draw_triplet"]


def _geom_patch(geom, **kw):
    """A matplotlib patch for a shapely (Multi)Polygon, holes included."""
    verts, codes = [], []
    polys = geom.geoms if hasattr(geom, "geoms") else [geom]
    for poly in polys:
        if poly.is_empty or poly.geom_type != "Polygon":
            continue
        for ring in [poly.exterior, *poly.interiors]:
            xy = np.asarray(ring.coords)
            verts.append(xy)
            codes += [MplPath.MOVETO] + [MplPath.LINETO] * (len(xy) - 2) + [MplPath.CLOSEPOLY]
    if not verts:
        return None
    return PathPatch(MplPath(np.concatenate(verts), codes), **kw)


def draw_partition(partition="edc", ax=None, *, probabilities=None, highlight=None,
                   label_states=True, cmap="Greens", colorbar=True):
    """Draw a partition's states in the AB frame, with A, B and the 1-based labels.

    ``probabilities``: (m,) values shading each state, explained by a colour bar (``colorbar``);
    ``highlight``: a 0-based state outlined in red.
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize

    part = _partitions.get(partition)
    if ax is None:
        _, ax = plt.subplots(figsize=(5, 6))
    colors = plt.get_cmap("tab20")(np.arange(part.n_states) % 20)
    if probabilities is not None:
        p = np.asarray(probabilities, dtype=float)
        top = max(float(p.max()), 1e-12)
        # the lightest 10% and darkest 5% of the map are left out: 0 stays visible as a tint
        # and the labels stay readable on the most likely state
        shades = ListedColormap(plt.get_cmap(cmap)(np.linspace(0.1, 0.95, 256)))
        colors = shades(p / top)
        if colorbar:
            sm = ScalarMappable(norm=Normalize(0.0, top), cmap=shades)
            ax.figure.colorbar(sm, ax=ax, shrink=0.75, pad=0.02,
                               label="probability of the state")
    for i, poly in enumerate(part.polygons):
        patch = _geom_patch(poly, facecolor=colors[i], edgecolor="0.3", lw=0.6,
                            alpha=0.9 if probabilities is not None else 0.45)
        if patch is not None:
            ax.add_patch(patch)
        if label_states:
            rp = shapely.point_on_surface(poly)
            ax.text(rp.x, rp.y, part.labels[i], ha="center", va="center", fontsize=7)
    if highlight is not None:
        patch = _geom_patch(part.polygons[int(highlight)], facecolor="none", edgecolor="red", lw=2)
        if patch is not None:
            ax.add_patch(patch)
    ax.plot([0, 0], [0, 1], "k-", lw=1)
    ax.plot([0, 0], [0, 1], "ko", ms=4)
    ax.annotate("A", (0, 0), xytext=(4, -10), textcoords="offset points")
    ax.annotate("B", (0, 1), xytext=(4, 4), textcoords="offset points")
    xmin, xmax, ymin, ymax = part.window
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x in the AB frame [|AB|]")
    ax.set_ylabel("y in the AB frame [|AB|]")
    ax.set_title(f"{part.name.upper()} ({part.n_states} states)")
    return ax


def draw_scenario(scenario, ax=None, *, triplet=None):
    """Landmarks (numbered), the camera path with headings, and sight lines of one triplet."""
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    L, P = scenario.landmarks, scenario.poses
    ax.plot(P[:, 0], P[:, 1], "-", color="tab:red", lw=0.8, alpha=0.6, label="camera path")
    ax.quiver(P[:, 0], P[:, 1], np.cos(P[:, 2]), np.sin(P[:, 2]), color="tab:red", scale=25,
              width=0.004)
    ax.plot(L[:, 0], L[:, 1], "s", color="tab:blue", label="landmarks")
    for i, (x, y) in enumerate(L):
        ax.annotate(str(i), (x, y), xytext=(4, 4), textcoords="offset points", color="tab:blue")
    if triplet is not None:
        for v in triplet.views:
            for lid in triplet.landmarks:
                ax.plot([P[v, 0], L[lid, 0]], [P[v, 1], L[lid, 1]], ":", color="0.5", lw=0.7)
    ax.set_aspect("equal")
    ax.set_xlabel("x [world units]")
    ax.set_ylabel("y [world units]")
    if triplet is not None:
        ax.plot([], [], ":", color="0.5", lw=0.7, label="sight lines of the triplet")
    # below the axes: inside, a legend covers part of the path wherever it goes
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=7, frameon=False)
    ax.set_title("scenario (world frame)")
    return ax


def draw_triplet(history, ax=None, *, partition="edc", probabilities=None):
    """A triplet in its AB frame: the partition, C's true state, true camera positions."""
    ax = draw_partition(partition, ax, probabilities=probabilities,
                        highlight=None if history.truth is None else history.truth.state)
    if history.truth is not None:
        c = history.truth.C_ab
        ax.plot(c[0], c[1], "r*", ms=12, label="C (truth)")
        ax.plot([], [], "-", color="red", lw=2, label="its state (outlined)")
        cams = history.truth.poses_ab
        if cams is not None:  # None for real data without camera ground truth
            ax.plot(cams[:, 0], cams[:, 1], "^", color="tab:purple", label="cameras (truth)")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.11), ncol=3, fontsize=7,
                  frameon=False)
    a, b, c = history.landmarks
    ax.set_title(f"triplet {a},{b}:{c} in its AB frame")
    return ax
