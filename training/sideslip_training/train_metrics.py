"""The figures ``sideslip-train`` reports for a trained model: its errors on the
validation windows, and the exported model's and the baselines' on the test runs."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from .dataset import Run
from .export import load_model
from .inputs import InputSpec
from .normalize import Normalizer
from .trainer import TrainResult
from .windows import WindowIndex


def val_metrics(result: TrainResult, val: WindowIndex, normalizer: Normalizer) -> dict[str, float]:
    """Validation errors in degrees against the exact (float64) ground truth: mean
    absolute, root mean square and mean (signed, β̂ − β) error."""
    import torch

    est = np.empty(len(val.ends))
    with torch.inference_mode():
        for start in range(0, len(val.ends), 8192):
            x, _ = val.batch(np.arange(start, min(start + 8192, len(val.ends))))
            est[start : start + x.shape[0]] = result.model(torch.from_numpy(x)).numpy()
    beta_hat = normalizer.invert_beta(est) + val.prior_rad[val.ends]
    err = np.degrees(beta_hat - val.beta_rad[val.ends])
    return {
        "val_mae_deg": float(np.mean(np.abs(err))),
        "val_rmse_deg": float(np.sqrt(np.mean(err**2))),
        "val_me_deg": float(np.mean(err)),
    }


def pooled_test_metrics(
    model_path: Path,
    runs: Sequence[Run],
    log: Callable[[str], None],
    spec: InputSpec | None = None,
) -> dict[str, dict[str, float]]:
    """The exported model and the baselines on the test runs, pooled over their samples:
    per estimator its MAE and RMSE [deg], R² and sample count. ``spec``: the training's
    inputs, whose car and ``ukf`` params file serve test runs whose bags record no car
    (a real recording), as they served its training runs."""
    from .evaluate import evaluate_runs, interval_coverage, model_label, pooled

    net, meta = load_model(model_path)
    traces = evaluate_runs(
        runs,
        [(model_label(meta), net, meta)],
        window_steps=meta.window_steps,
        dt_s=meta.dt_s,
        vehicle=spec.vehicle if spec is not None else None,
        observer_params_file=spec.observer_params_file if spec is not None else None,
        car=spec.car if spec is not None else "recorded",
        # The trained network itself, also beyond its recordings' range (the node and
        # sideslip-fit's card hand over to the start model there: beyond_fit_range).
        beyond_fit_range="model",
        mirror_average=False,  # as validated and selected (the node's auto may average it)
    )
    out: dict[str, dict[str, float]] = {
        name: {"mae_deg": m.mae, "rmse_deg": m.rmse, "r2": m.r2, "samples": m.n}
        for name, m in pooled(traces).items()
    }
    for name, figures in out.items():
        mine = [t for t in traces if t.estimator == name and t.sigma_rad is not None]
        if mine:  # the model's published σ: the share of test samples inside ±1.96 σ
            figures["coverage_95"] = interval_coverage(mine)
    log(
        "test (pooled over "
        + f"{len(runs)} run(s)): "
        + "; ".join(
            f"{n} MAE {v['mae_deg']:.4f} deg"
            + (f", {v['coverage_95']:.3f} inside ±1.96 σ" if "coverage_95" in v else "")
            for n, v in out.items()
        )
    )
    return out
