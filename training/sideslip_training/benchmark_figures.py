"""The figures of ``sideslip-benchmark`` (PNG, for its README): MAE per car × μ and per
run, and β traces of each car."""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .benchmark_estimators import KINEMATIC_RAW
from .benchmark_scores import RunResult, Summary


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_mae_by_cell(summary: Summary, path: Path) -> Path:
    """Grouped bars: MAE [deg] of every estimator in every car × μ cell (log scale)."""
    plt = _pyplot()
    cells = list(summary.cells)
    labels = summary.labels
    width = 0.8 / len(labels)
    fig, ax = plt.subplots(figsize=(max(10.0, 0.75 * len(cells) + 4), 4.8))
    x = np.arange(len(cells))
    for i, lab in enumerate(labels):
        maes = [summary.cells[c][lab].mae_deg for c in cells]
        ax.bar(x + (i - (len(labels) - 1) / 2) * width, maes, width, label=lab)
    ax.set_xticks(x, [f"{v.removeprefix('heldout_')}\nμ={mu:.1f}" for v, mu in cells], fontsize=7)
    ax.set_yscale("log")
    ax.set(ylabel="MAE [deg]", title="Held-out benchmark: MAE per car × μ")
    ax.grid(axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=min(len(labels), 4))
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _trace_runs(summary: Summary, vehicle: str) -> list[RunResult]:
    """The runs a car's trace figure shows: at μ = 1.0 and 0.4 (else the μ there are), its
    scen2, else its sweep, else its first run."""
    mine = [r for r in summary.runs if r.run.vehicle_name == vehicle]
    mus = sorted({r.run.mu for r in mine}, reverse=True)
    wanted = [mu for mu in (1.0, 0.4) if mu in mus] or mus[:2]
    chosen = []
    for mu in wanted:
        at_mu = [r for r in mine if r.run.mu == mu]
        for kind in ("scen2", "sweep_steer"):
            pick = next((r for r in at_mu if r.run.kind == kind), None)
            if pick is not None:
                break
        chosen.append(pick or at_mu[0])
    return chosen


def plot_vehicle_traces(summary: Summary, vehicle: str, path: Path) -> Path:
    """β and every estimate [deg] over time on the car's μ = 1.0 and μ = 0.4 runs."""
    plt = _pyplot()
    runs = _trace_runs(summary, vehicle)
    fig, axes = plt.subplots(len(runs), 1, figsize=(10, 3.4 * len(runs)), squeeze=False)
    for ax, r in zip(axes[:, 0], runs, strict=True):
        for lab in summary.labels:
            faint = lab == KINEMATIC_RAW  # noise around the reference: drawn faint, behind
            ax.plot(
                r.t_s,
                np.degrees(r.estimates[lab]),
                lw=0.5 if faint else 1.0,
                alpha=0.3 if faint else 0.9,
                label=lab,
            )
        ax.plot(r.t_s, np.degrees(r.reference_rad), "k--", lw=1.2, label="Reference")
        ax.set(
            xlabel="t [s]", ylabel="β [deg]", title=f"{vehicle}, μ = {r.run.mu:.1f}, {r.run.kind}"
        )
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=7, ncol=4)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_mae_per_run(summary: Summary, path: Path) -> Path:
    """Box plot of the per-run MAE [deg] of every estimator (log scale), runs as dots."""
    plt = _pyplot()
    labels = summary.labels
    data = [[r.score(lab).mae_deg for r in summary.runs] for lab in labels]
    fig, ax = plt.subplots(figsize=(max(7.0, 1.2 * len(labels) + 2), 4.5))
    ax.boxplot(data, whis=(0, 100))
    ax.set_xticks(np.arange(1, len(labels) + 1), labels, fontsize=7, rotation=20, ha="right")
    rng = np.random.default_rng(0)  # jitter only, fixed so the figure is reproducible
    for i, values in enumerate(data, start=1):
        ax.plot(
            i + rng.uniform(-0.15, 0.15, len(values)), values, ".", color="0.3", ms=3, alpha=0.6
        )
    ax.set_yscale("log")
    ax.set(
        ylabel="MAE per run [deg]",
        title=f"Held-out benchmark: MAE of each of the {len(summary.runs)} runs",
    )
    ax.grid(axis="y", which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_all(summary: Summary, folder: Path, *, progress: bool) -> list[Path]:
    """Every figure into ``folder``: MAE per cell, MAE per run, and each car's traces."""
    from tqdm import tqdm

    folder.mkdir(parents=True, exist_ok=True)
    jobs: list[Callable[[], Path]] = [
        functools.partial(plot_mae_by_cell, summary, folder / "mae_by_cell.png"),
        functools.partial(plot_mae_per_run, summary, folder / "mae_per_run.png"),
        *(
            functools.partial(plot_vehicle_traces, summary, v, folder / f"trace_{v}.png")
            for v in summary.vehicles
        ),
    ]
    bar = tqdm(jobs, unit="figure", desc="figures", disable=not progress, file=sys.stderr)
    return [job() for job in bar]
