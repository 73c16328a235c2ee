"""Convergence plot of a PSO run: fitness per iteration and each particle's trajectory."""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from matplotlib import colormaps
from matplotlib.figure import Figure

from sideslip_training.pso import PsoHistory


def plot_convergence(
    history: PsoHistory,
    path: str | os.PathLike[str],
    *,
    fitness_label: str = "fitness (validation MAE)",
    title: str | None = None,
) -> Path:
    """Write a PNG/SVG/PDF (by suffix) with one panel per row:

    1. every particle's fitness per iteration (dots), failed or non-finite evaluations as
       crosses on the top edge, and the global best after each iteration (line); log y
       when the finite values span more than a decade and are all positive;
    2. one panel per search dimension: each particle's decoded value per iteration
       (a line per particle), the global best's value (black) and the bounds (dashed).

    Uses matplotlib's object API (no pyplot state), so it is safe in any backend and
    thread. Returns the path written.
    """
    path = Path(path)
    iterations = [it.iteration for it in history.iterations]
    records = history.particles
    n_particles = 1 + max((p.particle for p in records), default=-1)
    space = history.space

    fig = Figure(figsize=(7.0, 2.4 * (1 + len(space))), layout="constrained")
    axes = fig.subplots(1 + len(space), 1, sharex=True, squeeze=False)[:, 0]
    ax = axes[0]
    finite = [p for p in records if math.isfinite(p.fitness)]
    ax.scatter(
        [p.iteration for p in finite],
        [p.fitness for p in finite],
        s=12,
        alpha=0.6,
        color="tab:blue",
        label="particles",
    )
    best = [(it.iteration, it.best_fitness) for it in history.iterations]
    best = [(i, f) for i, f in best if math.isfinite(f)]
    if best:
        ax.plot(*zip(*best, strict=True), color="black", marker="o", ms=3, label="global best")
    values = np.array([p.fitness for p in finite])
    if values.size and values.min() > 0 and values.max() / values.min() > 10:
        ax.set_yscale("log")
    failed = [p for p in records if not math.isfinite(p.fitness)]
    if failed:
        ax.scatter(
            [p.iteration for p in failed],
            [1.0] * len(failed),
            transform=ax.get_xaxis_transform(),
            marker="x",
            color="tab:red",
            clip_on=False,
            label=f"failed / non-finite ({len(failed)})",
        )
    ax.set_ylabel(fitness_label)
    ax.legend(loc="upper right", fontsize="small")
    ax.grid(True, alpha=0.3)

    cmap = _particle_colors(n_particles)
    for ax, dim in zip(axes[1:], space, strict=True):
        for k in range(n_particles):
            track = [(p.iteration, p.params[dim.name]) for p in records if p.particle == k]
            if track:
                ax.plot(*zip(*track, strict=True), color=cmap[k], lw=1, marker=".", alpha=0.7)
        ax.plot(
            iterations,
            [it.best_params[dim.name] for it in history.iterations],
            color="black",
            lw=2,
            label="global best",
        )
        for bound in (dim.low, dim.high):
            ax.axhline(bound, color="grey", ls="--", lw=0.8)
        ax.set_ylabel(dim.name)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("iteration (0 = initial swarm)")
    if iterations:
        step = max(1, len(iterations) // 10)
        axes[-1].set_xticks(iterations[::step])
    fig.suptitle(
        title or f"PSO: {n_particles} particles, iterations 0-{max(iterations, default=0)}"
    )
    fig.savefig(path, dpi=120)
    return path


def _particle_colors(n: int) -> list[tuple[float, float, float, float]]:
    cmap = colormaps["viridis"]
    return [cmap(k / max(n - 1, 1)) for k in range(n)]


__all__ = ["plot_convergence"]
