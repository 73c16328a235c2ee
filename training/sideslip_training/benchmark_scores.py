"""Scores of ``sideslip-benchmark``: per run, cell, car and overall; the verdicts of issue 8.

Every estimator is scored on the same samples of a run: those with a full window
behind them (index ≥ window − 1, as :mod:`.evaluate`), less any sample where some
estimator gave no estimate (a physics filter below its minimum speed); those are
counted per estimator in ``results.json``. Errors are β̂ − β in degrees. A cell
(car × μ) pools the samples of its runs, a car pools its three cells, and the
overall figure is the mean over cells.

The pass/fail figures of issue 8: a network without Y_v (``measurable``) passes with
a mean MAE over cells ≤ 0.20° and, on every car, at most half the MAE of the better
physics filter; a network with Y_v passes when it is on no run worse (higher MAE)
than the 20-step kinematic mean and at most half its MAE on average (mean over runs
of the per-run ratio).

:func:`results_json` holds all of it for machines (``results.json``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from .benchmark_data import HeldOutRun
from .benchmark_estimators import (
    KINEMATIC_MEAN,
    KINEMATIC_RAW,
    PHYSICS_BACKENDS,
    SMOOTHING_STEPS,
    ZERO,
    Network,
    PhysicsFilter,
)

FloatArray = npt.NDArray[np.float64]

MEASURABLE_MAE_LIMIT_DEG: Final = 0.20
"""Issue 8: a measurable-feature network's mean MAE over cells, at most [deg]."""
PHYSICS_RATIO_LIMIT: Final = 0.5
"""Issue 8: its MAE over the better physics filter's, on every car, at most."""
KINEMATIC_RATIO_LIMIT: Final = 0.5
"""Issue 8: a Y_v network's mean per-run MAE ratio to the smoothed kinematic, at most."""


@dataclass(frozen=True)
class Score:
    """Errors of β̂ − β in degrees (R² dimensionless) over ``samples`` samples."""

    mae_deg: float
    me_deg: float
    rmse_deg: float
    r2: float
    max_abs_deg: float
    samples: int


def score_deg(err_deg: FloatArray, ref_deg: FloatArray) -> Score:
    """The metrics of errors ``err_deg`` against references ``ref_deg`` [deg]; R² is NaN
    when the reference is constant, every metric NaN when there is no sample.

    Not :func:`.evaluate.metrics_deg`: that has no max |error|, no empty case, and takes
    the difference after converting to degrees (results would move in the last digit)."""
    if err_deg.size == 0:
        return Score(math.nan, math.nan, math.nan, math.nan, math.nan, 0)
    ss_tot = float(np.sum((ref_deg - ref_deg.mean()) ** 2))
    return Score(
        mae_deg=float(np.mean(np.abs(err_deg))),
        me_deg=float(np.mean(err_deg)),
        rmse_deg=float(np.sqrt(np.mean(err_deg**2))),
        r2=1.0 - float(np.sum(err_deg**2)) / ss_tot if ss_tot > 0 else math.nan,
        max_abs_deg=float(np.max(np.abs(err_deg))),
        samples=int(err_deg.size),
    )


@dataclass(frozen=True, eq=False)
class RunResult:
    """Every estimator on one run, over the run's samples from index window − 1 on.

    ``estimates`` hold NaN where an estimator gave none; ``scored`` marks the samples
    every estimator has, on which all are scored."""

    run: HeldOutRun
    t_s: FloatArray
    reference_rad: FloatArray
    estimates: dict[str, FloatArray]
    scored: npt.NDArray[np.bool_]

    def errors_deg(self, label: str) -> FloatArray:
        return np.degrees(self.estimates[label][self.scored] - self.reference_rad[self.scored])

    def reference_deg(self) -> FloatArray:
        return np.degrees(self.reference_rad[self.scored])

    def score(self, label: str) -> Score:
        return score_deg(self.errors_deg(label), self.reference_deg())

    def without_estimate(self, label: str) -> int:
        return int(np.count_nonzero(~np.isfinite(self.estimates[label])))


def collect(
    run: HeldOutRun,
    *,
    window_steps: int,
    physics: Mapping[str, FloatArray],
    networks: Mapping[str, FloatArray],
) -> RunResult:
    """A run's estimates in column order, cut to samples[window-1:], and the scored mask."""
    from .evaluate import kinematic

    s = run.run.samples
    start = window_steps - 1
    reference = s.beta_rad()[start:]
    estimates: dict[str, FloatArray] = {
        ZERO: np.zeros_like(reference),
        KINEMATIC_RAW: kinematic(run.run, 1, window_steps),
        KINEMATIC_MEAN: kinematic(run.run, SMOOTHING_STEPS, window_steps),
    }
    estimates |= {label: beta[start:] for label, beta in physics.items()}
    estimates |= dict(networks)
    for label, est in estimates.items():
        if est.shape != reference.shape:
            raise RuntimeError(
                f"{run.name}: {label} gave {est.shape[0]} estimates for "
                f"{reference.shape[0]} samples"
            )
    scored = np.isfinite(reference)
    for est in estimates.values():
        scored &= np.isfinite(est)
    t_s = (s.stamp_ns[start:] - s.stamp_ns[0]) * 1e-9
    return RunResult(run, t_s, reference, estimates, scored)


def pooled(results: Iterable[RunResult], label: str) -> Score:
    """One score over the samples of all ``results`` (pooled, not averaged)."""
    results = list(results)
    if not results:
        return score_deg(np.empty(0), np.empty(0))
    return score_deg(
        np.concatenate([r.errors_deg(label) for r in results]),
        np.concatenate([r.reference_deg() for r in results]),
    )


def _mean(values: Iterable[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


@dataclass(frozen=True)
class Summary:
    """Per-run, per-cell, per-car and overall scores of every estimator (column order)."""

    labels: tuple[str, ...]
    runs: tuple[RunResult, ...]
    cells: dict[tuple[str, float], dict[str, Score]]
    vehicles: dict[str, dict[str, Score]]
    overall: dict[str, dict[str, float]]
    """Mean over cells of each metric (R² over the cells where it is defined)."""


def summarize(results: Sequence[RunResult], labels: Sequence[str]) -> Summary:
    cells: dict[tuple[str, float], list[RunResult]] = {}
    vehicles: dict[str, list[RunResult]] = {}
    for r in results:
        cells.setdefault(r.run.cell, []).append(r)
        vehicles.setdefault(r.run.vehicle_name, []).append(r)
    cell_scores = {c: {lab: pooled(rs, lab) for lab in labels} for c, rs in cells.items()}
    overall = {
        lab: {
            k: _mean(getattr(cell_scores[c][lab], k) for c in cell_scores)
            for k in ("mae_deg", "me_deg", "rmse_deg", "r2", "max_abs_deg")
        }
        for lab in labels
    }
    return Summary(
        labels=tuple(labels),
        runs=tuple(results),
        cells=cell_scores,
        vehicles={v: {lab: pooled(rs, lab) for lab in labels} for v, rs in vehicles.items()},
        overall=overall,
    )


# --- pass / fail ----------------------------------------------------------------------------


@dataclass(frozen=True)
class Check:
    """One pass/fail criterion of issue 8 and what was measured."""

    criterion: str
    measured: str
    passed: bool | None  # None: cannot be decided (e.g. no physics filter ran)


@dataclass(frozen=True)
class Verdict:
    network: str
    features: str  # "measurable" (no Y_v) or "with Y_v"
    runs_worse_than_kinematic: tuple[str, ...]
    mean_ratio_to_kinematic: float
    ratio_to_best_physics: dict[str, float] = field(default_factory=dict)
    checks: tuple[Check, ...] = ()

    @property
    def passed(self) -> bool | None:
        if any(c.passed is None for c in self.checks):
            return None
        return all(c.passed for c in self.checks)


def best_physics_mae(summary: Summary, vehicle: str) -> float:
    """The better physics filter's MAE on a car [deg] (NaN when none ran)."""
    maes = [
        summary.vehicles[vehicle][lab].mae_deg for lab in PHYSICS_BACKENDS if lab in summary.labels
    ]
    return min(maes) if maes else math.nan


def verdicts(summary: Summary, networks: Sequence[Network]) -> list[Verdict]:
    out = []
    for net in networks:
        lab = net.label
        worse = tuple(
            r.run.name
            for r in summary.runs
            if r.score(lab).mae_deg > r.score(KINEMATIC_MEAN).mae_deg
        )
        ratio = _mean(r.score(lab).mae_deg / r.score(KINEMATIC_MEAN).mae_deg for r in summary.runs)
        n_runs = len(summary.runs)
        if net.uses_lateral_velocity:
            checks = (
                Check(
                    f"on no run worse than {KINEMATIC_MEAN}",
                    f"worse on {len(worse)} of {n_runs}",
                    not worse,
                ),
                Check(
                    f"mean MAE ratio to {KINEMATIC_MEAN} ≤ {KINEMATIC_RATIO_LIMIT:g}",
                    f"{ratio:.3f}",
                    ratio <= KINEMATIC_RATIO_LIMIT,
                ),
            )
            out.append(Verdict(lab, "with Y_v", worse, ratio, checks=checks))
            continue
        mae = summary.overall[lab]["mae_deg"]
        ratios = {
            v: scores[lab].mae_deg / best_physics_mae(summary, v)
            for v, scores in summary.vehicles.items()
        }
        worst = max(ratios.values(), default=math.nan)
        decided = all(math.isfinite(x) for x in ratios.values()) and ratios
        checks = (
            Check(
                f"mean MAE over cells ≤ {MEASURABLE_MAE_LIMIT_DEG:.2f}°",
                f"{mae:.3f}°",
                mae <= MEASURABLE_MAE_LIMIT_DEG,
            ),
            Check(
                f"MAE ≤ {PHYSICS_RATIO_LIMIT:g} × the better physics filter's, every car",
                f"worst ratio {worst:.3f}",
                (worst <= PHYSICS_RATIO_LIMIT) if decided else None,
            ),
        )
        out.append(Verdict(lab, "measurable", worse, ratio, ratios, checks))
    return out


# --- results.json ---------------------------------------------------------------------------


def results_json(
    summary: Summary,
    networks: Sequence[Network],
    filters: Sequence[PhysicsFilter],
    notes: Sequence[str],
    context: Mapping[str, Any],
) -> dict[str, Any]:
    """Everything measured, for machines: what ran, per run, per cell, per car, overall."""
    from .evaluate import json_ready

    return json_ready(
        {
            **context,
            "estimators": list(summary.labels),
            "networks": [
                {
                    "label": n.label,
                    "path": str(n.path),
                    "architecture": n.meta.architecture,
                    "hidden_units": n.meta.hidden_units,
                    "features": list(n.meta.features),
                    "training_data_digest": n.meta.training_data_digest,
                    "created_utc": n.meta.created_utc,
                }
                for n in networks
            ],
            "physics_filters": [asdict(f) for f in filters],
            "notes": list(notes),
            "runs": [
                {
                    "run": r.run.name,
                    "vehicle": r.run.vehicle_name,
                    "mu": r.run.mu,
                    "kind": r.run.kind,
                    "spin_onset_s": r.run.spin_onset_s,
                    "noise": r.run.noise,
                    "samples": int(r.scored.sum()),
                    "estimators": {
                        lab: {**asdict(r.score(lab)), "without_estimate": r.without_estimate(lab)}
                        for lab in summary.labels
                    },
                }
                for r in summary.runs
            ],
            "cells": [
                {
                    "vehicle": v,
                    "mu": mu,
                    "runs": sum(1 for r in summary.runs if r.run.cell == (v, mu)),
                    "estimators": {lab: asdict(s) for lab, s in scores.items()},
                }
                for (v, mu), scores in summary.cells.items()
            ],
            "vehicles": [
                {"vehicle": v, "estimators": {lab: asdict(s) for lab, s in scores.items()}}
                for v, scores in summary.vehicles.items()
            ],
            "overall_mean_over_cells": summary.overall,
            "verdicts": [{**asdict(v), "passed": v.passed} for v in verdicts(summary, networks)],
        }
    )
