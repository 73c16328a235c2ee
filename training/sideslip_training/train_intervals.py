"""The per-sample σ a model leaves ``sideslip-train`` with (``--intervals``).

A trained or fine-tuned model without an uncertainty model publishes its validation
RMSE² as a constant variance, whatever the driving. ``sideslip-train`` calibrates it as
``sideslip-calibrate`` would (:func:`.calibrate.calibrate`), on the validation runs and
with the model that early stopping chose, **before** any refit: those runs are the only
data that model has not trained on. The refit model (trained again on training +
validation) then carries that σ; it has seen more data, so its intervals lean wide
rather than narrow (measured in docs/evaluation/intervals, "Fitted models").
With ``--folds K`` the validation runs are every bag instead, each scored by the fold
network that did not train on it (:mod:`.fold_calibration`): K times the data.

Policies:

- ``scale``: keep the σ terms of the ``--init`` model (fitted on a fleet) and fit only
  the conformal scale on all the validation runs: minutes of one car's driving fix an
  error level, not four coefficients; works with a single recording. That scale holds
  for driving like the recordings'; the model also records their range of lateral
  acceleration and sideslip rate (:class:`~sideslip_msgs_py.uncertainty.FitRange`),
  and while the input window reaches beyond it σ takes :data:`OUTSIDE_FACTOR` times
  the ``--init`` model's scale when that is wider: a limit manoeuvre the recordings
  lack is where the fine-tuned network extrapolates;
- ``fit``: terms by likelihood on half the validation bags, the scale on the other half
  (needs at least two validation bags);
- ``auto`` (default): ``scale`` when fine-tuning a model that has σ terms, else ``fit``
  when there are two or more validation bags, else none;
- ``no``: none (the constant validation RMSE²).
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Any, Final

from sideslip_msgs_py.data_source import mirror_average_on

from .cli_errors import CliError
from .dataset import DatasetError, Run
from .train_plan import TrainPlan

INTERVAL_POLICIES: Final = ("auto", "scale", "fit", "no")
OUTSIDE_FACTOR: Final = 2.0
"""Beyond the recordings' range σ takes this many times the start model's scale (if
wider than the car's own). Chosen on validation cars whose own recordings stayed under
4 m/s² and whose other drives did not (docs/evaluation/intervals, "Beyond the
recordings"): 1, 1.5, 2 and 3 were compared; the held-out cars were not used."""


def interval_mode(
    policy: str, plan: TrainPlan, folds: Sequence[Sequence[Run]] | None = None
) -> str | None:
    """What ``policy`` does for this training: ``scale``, ``fit`` or None; ``folds``: the
    runs dealt into folds (``--folds``), whose bags the intervals are calibrated on
    instead of the validation bags.

    Raises CliError, before anything is trained, for an explicit policy the training
    cannot follow."""
    if policy not in INTERVAL_POLICIES:
        raise CliError(f"--intervals must be one of {', '.join(INTERVAL_POLICIES)}, got {policy}")
    init_has_terms = plan.init is not None and plan.init.meta.uncertainty is not None
    # A mirror image stays in its run's bag: it adds no bag.
    runs = plan.data.val_runs if folds is None else [r for g in folds for r in g]
    val_bags = len({r.bag for r in runs})
    if policy == "scale" and not init_has_terms:
        raise CliError(
            "--intervals scale keeps the σ terms of the --init model, but "
            + ("there is no --init" if plan.init is None else f"{plan.init.path.name} has none")
            + ": use --intervals fit or auto"
        )
    if policy == "fit" and val_bags < 2:
        raise CliError(
            f"--intervals fit needs two or more validation bags (one half fits the σ "
            f"terms, the other their scale), got {val_bags}: use --intervals scale with an "
            "--init model that has σ terms, or give more bags"
        )
    if policy == "auto":
        if init_has_terms:
            return "scale"
        return "fit" if val_bags >= 2 else None
    return None if policy == "no" else policy


def calibrate_selection(
    mode: str | None,
    plan: TrainPlan,
    model: Any,
    meta: Any,
    seed: int,
    log: Callable[[str], None],
    policy: str = "auto",
    folds: Sequence[tuple[Sequence[Run], Any]] | None = None,
) -> tuple[dict[str, Any] | None, dict[str, float] | None]:
    """The uncertainty model (:meth:`~sideslip_msgs_py.uncertainty.Uncertainty.to_dict`)
    and the calibration's figures for the selected ``model`` (metadata ``meta``), fitted
    on the validation runs, or with ``folds`` (``--folds``: each fold's runs and the
    network trained without them) on the out-of-fold errors of every fold's recorded
    runs (:mod:`.fold_calibration`); (None, None) for ``mode`` None or when the
    calibration cannot be made (too few scored samples, a filter or feature that fails
    on the runs): the model is still exported, with its validation RMSE² as σ, and an
    explicit ``policy`` (``scale``, ``fit``) says so on stderr even with --quiet."""
    from sideslip_msgs_py.features import FeatureError

    from .calibrate import calibrate
    from .filter_replay import FilterError
    from .fold_calibration import out_of_fold_errors

    if mode is None:
        why = (
            "--intervals no"
            if policy == "no"
            else "no σ terms to keep and fewer than two validation bags"
        )
        log(f"intervals: none ({why})")
        return None, None
    spec = plan.spec
    car = {
        "vehicle": spec.vehicle,
        "observer_params_file": spec.observer_params_file,
        "car": spec.car,
    }
    try:
        if mode == "scale":
            start = _start_sigma(plan, meta, car, log)
            meta = replace(meta, uncertainty=start.to_dict())
        # σ for what the node publishes by default: a model that learnt from simulated
        # runs alone averaged with its mirror image (pso_lstm.mirror_average auto).
        mirror = mirror_average_on("auto", meta.provenance)
        scoring = {**car, "mirror_average": mirror}
        runs, errors = plan.data.val_runs, None
        if folds is not None:
            runs, errors = out_of_fold_errors(folds, meta, scoring)
        unc, figures = calibrate(
            runs,
            model,
            meta,
            seed=seed,
            scale_only=mode == "scale",
            car=scoring,
            errors=errors,
        )
        figures = {**figures, "mirror_averaged": float(mirror)}
        if errors is not None:
            figures = {**figures, "out_of_fold_folds": float(len(folds or ()))}
        if mode == "scale":
            unc = replace(unc, fit_range=_fit_range(plan, start.scale))
    except (DatasetError, FilterError, FeatureError, ValueError) as err:
        log(f"intervals: none ({err})")
        if policy != "auto":
            print(
                f"sideslip-train: warning: --intervals {policy} could not be calibrated "
                f"({err}); the model publishes its validation RMSE² as σ",
                file=sys.stderr,
            )
        return None, None
    fit = unc.fit_range
    if mode == "scale" and fit is not None:
        log(
            f"intervals: the recordings span |a_y| ≤ {fit.lateral_acceleration_mps2:.2f} m/s², "
            f"|β̇| ≤ {fit.beta_rate_radps:.3f} rad/s; while the window reaches beyond, "
            f"scale {fit.outside_scale:.3f} ({OUTSIDE_FACTOR:g} × the start's) when wider"
        )
    where = (
        "on the validation runs with the selected model"
        if folds is None
        else f"out of fold: {len(folds)} fold(s), each scored by the network that missed it"
    )
    log(
        f"intervals ({mode}, {where}): scale "
        f"{unc.scale:.3f}, {figures['coverage_scale_half']:.3f} of the samples inside "
        f"±1.96 σ; per run {figures['coverage_per_run_min']:.3f} (min) to "
        f"{figures['coverage_per_run_median']:.3f} (median)"
    )
    return unc.to_dict(), figures


def _start_sigma(
    plan: TrainPlan, meta: Any, car: dict[str, Any], log: Callable[[str], None]
) -> Any:
    """The σ whose terms ``scale`` keeps (an :class:`Uncertainty`): the --init model's
    own, or where every validation run reads a UKF file made from a description and the
    --init model carries a σ for such files (``sideslip-calibrate --car described``),
    that one: it was fitted where the filter's tyres are guessed, as here."""
    from sideslip_msgs_py.uncertainty import Uncertainty

    from .calibrate import described_kinds

    assert plan.init is not None and plan.init.meta.uncertainty is not None
    start = Uncertainty.from_dict(plan.init.meta.uncertainty)
    if start.described is not None and described_kinds(plan.data.val_runs, meta, car) == {True}:
        log("intervals: the runs read described car files: scaling the start's σ for those")
        return start.described
    # The fine-tuned model's σ is for the files it was calibrated with, and it carries a
    # fit range, which a σ for described files may not sit beside.
    return replace(start, described=None)


def _fit_range(plan: TrainPlan, start_scale: float) -> Any:
    """The range of the recordings the model was fine-tuned and calibrated on, with
    :data:`OUTSIDE_FACTOR` times the scale of the ``--init`` model's σ whose terms were
    kept (``start_scale``) for beyond it."""
    import numpy as np

    from sideslip_msgs_py.uncertainty import FitRange

    assert plan.init is not None
    # The recordings only: rehearsal trains the model beyond them, but the scale was
    # calibrated on the recordings, and it is their range the σ is known to hold in.
    runs = [*plan.data.recorded_train_runs, *plan.data.val_runs]
    return FitRange.of_samples(
        *(
            np.concatenate([getattr(r.samples, name) for r in runs])
            for name in ("x_v_mps", "y_a_mps2", "yaw_rate_radps")
        ),
        outside_scale=OUTSIDE_FACTOR * start_scale,
        window_steps=plan.init.meta.window_steps,
    )
