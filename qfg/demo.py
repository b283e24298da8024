"""The ``qfg demo``: a small simulated scenario, its ground-truth qualitative map, and figures."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from . import partitions
from .simulation import random_scenario, triplet_histories


def run(seed: int = 0, output: str | Path = "out/demo", n_landmarks: int = 6, n_poses: int = 12,
        landmarks_per_view: int = 4, partition: str = "edc", echo=print) -> dict:
    """Simulate, print the ground-truth map and write ``scenario.png``; return what was made."""
    rng = np.random.default_rng(seed)
    part = partitions.get(partition)
    sc = random_scenario(rng, n_landmarks, n_poses, landmarks_per_view,
                         sigma_bearing=np.deg2rad(2.0), sigma_heading=np.deg2rad(5.0))
    hist = triplet_histories(sc, partition=part.name)
    echo(f"qfg demo: {n_landmarks} landmarks, {n_poses} poses, {landmarks_per_view} landmarks per "
         f"view, seed {seed}")
    echo(f"{len(hist)} ordered triplets seen together at least once; ground-truth "
         f"{part.name.upper()} states (1-based):")
    echo(f"{'triplet':>9}  {'views':>5}  state  region")
    for h in hist:
        a, b, c = h.landmarks
        s = h.truth.state
        echo(f"{f'{a},{b}:{c}':>9}  {h.n_views:5d}  {part.labels[s]:>5}  {part.descriptions[s]}")
    out = Path(output)
    out.mkdir(parents=True, exist_ok=True)
    fig_path = out / "scenario.png"
    if hist:
        best = max(hist, key=lambda h: h.n_views)
        _figure(sc, best, part, fig_path)
        echo(f"figure: {fig_path} (scenario, and triplet "
             f"{best.landmarks[0]},{best.landmarks[1]}:{best.landmarks[2]} in its AB frame)")
    return {"scenario": sc, "histories": hist, "figure": fig_path if hist else None}


def _figure(scenario, history, part, path):
    from .plotting import draw_scenario, draw_triplet, plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 5.5))
    draw_scenario(scenario, axes[0], triplet=history)
    draw_triplet(history, axes[1], partition=part)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
