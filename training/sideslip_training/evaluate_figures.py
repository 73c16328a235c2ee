"""The evaluation's figures: β traces (the paper's Figs. 7–10, 15–18), error PDFs
(Figs. 11–14) and, for a model that publishes σ, its 95 % band."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from sideslip_msgs_py.uncertainty import Z_95

from .evaluate import Trace


def plot_traces(traces: Sequence[Trace], out_dir: Path, prefix: str = "") -> list[Path]:
    """One figure per scenario: β reference and every estimate [deg] over time."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for scen in dict.fromkeys(t.scenario for t in traces):
        mine = [t for t in traces if t.scenario == scen]
        fig, ax = plt.subplots(figsize=(9, 3.6))
        for t in mine:
            # The raw baseline is noise around the reference: drawn faint, behind.
            faint = "raw" in t.estimator
            ax.plot(
                t.t_s,
                np.degrees(t.estimate_rad),
                lw=0.6 if faint else 1.0,
                alpha=0.3 if faint else 0.9,
                label=t.estimator,
            )
        ax.plot(mine[0].t_s, np.degrees(mine[0].reference_rad), "k--", lw=1.2, label="Reference")
        ax.set(xlabel="t [s]", ylabel="β [deg]", title=f"{scen}: sideslip angle")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, ncol=3)
        fig.tight_layout()
        path = out_dir / f"{prefix}trace_{scen}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_error_pdfs(traces: Sequence[Trace], out_dir: Path, prefix: str = "") -> list[Path]:
    """One figure per scenario: Gaussian fit of each estimator's error with mean ± std."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = []
    for scen in dict.fromkeys(t.scenario for t in traces):
        mine = [t for t in traces if t.scenario == scen]
        fig, ax = plt.subplots(figsize=(7, 3.6))
        for i, t in enumerate(mine):
            err = np.degrees(t.estimate_rad - t.reference_rad)
            err = err[np.isfinite(err)]
            if err.size == 0:
                continue
            mu, sd = float(err.mean()), float(err.std())
            xs = np.linspace(mu - 4 * sd, mu + 4 * sd, 200) if sd > 0 else np.array([mu])
            pdf = (
                np.exp(-0.5 * ((xs - mu) / sd) ** 2) / (sd * math.sqrt(2 * math.pi))
                if sd > 0
                else xs * 0 + 1
            )
            (line,) = ax.plot(xs, pdf, lw=1.2, label=f"{t.estimator}: {mu:+.3f} ± {sd:.3f}")
            peak = float(pdf.max())
            ax.plot([mu], [peak], "o", color=line.get_color())
            ax.hlines(peak * (1 - 0.03 * i), mu - sd, mu + sd, color=line.get_color())
        ax.set(xlabel="β̂ − β [deg]", ylabel="density", title=f"{scen}: error PDF")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = out_dir / f"{prefix}error_pdf_{scen}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def plot_band(trace: Trace, path: Path) -> Path:
    """One run: the reference, the estimate and its published 95 % band [deg]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if trace.sigma_rad is None:
        raise ValueError(f"{trace.estimator} publishes no per-sample σ")
    est, sig = np.degrees(trace.estimate_rad), np.degrees(trace.sigma_rad)
    fig, ax = plt.subplots(figsize=(9, 3.6))
    ax.fill_between(
        trace.t_s, est - Z_95 * sig, est + Z_95 * sig, alpha=0.3, lw=0, label="β̂ ± 1.96 σ"
    )
    ax.plot(trace.t_s, est, lw=1.0, label=trace.estimator)
    ax.plot(trace.t_s, np.degrees(trace.reference_rad), "k--", lw=1.0, label="Reference")
    ax.set(
        xlabel="t [s]",
        ylabel="β [deg]",
        title=f"{trace.scenario}: {trace.coverage:.1%} of samples inside the band",
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
