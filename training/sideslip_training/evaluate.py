"""Evaluation in the paper's layout: MAE, ME, RMSE, R² in degrees per scenario and model,
β traces (Figs. 7–10, 15–18) and error PDFs (Figs. 11–14), with the kinematic baseline
atan2(Y_v, X_v), raw and smoothed, beside every learned model.

Every estimator is scored on the same samples: those with a full window behind them
(sample index ≥ window − 1 of each run), so the baselines are not credited with the
first 250 ms that a network cannot see. Tables of the traces: :mod:`.evaluate_tables`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import torch

from sideslip_msgs_py.artifact import ModelMetadata, zscore
from sideslip_msgs_py.data_source import mirror_average_on
from sideslip_msgs_py.fleet_envelope import FleetEnvelope, publishes_prior
from sideslip_msgs_py.mirror import input_signs
from sideslip_msgs_py.model_inputs import INPUT_SETS
from sideslip_msgs_py.timing import STEP_S
from sideslip_msgs_py.uncertainty import Z_95, Uncertainty
from sideslip_msgs_py.vehicle_description import VehicleDescription

from .dataset import Run
from .filter_replay import FILTER_LABELS, physics_filter
from .inputs import InputSpec
from .model import SideslipNet

FloatArray = npt.NDArray[np.float64]
PREDICT_BATCH = 4096


@dataclass(frozen=True)
class Metrics:
    """Errors of β̂ − β in degrees (R² dimensionless), over the ``n`` samples where both
    are finite; ``excluded`` samples were not (NaN when ``n`` is 0)."""

    mae: float
    me: float
    rmse: float
    r2: float
    n: int
    excluded: int = 0


def metrics_json(m: Metrics) -> dict[str, float | int | None]:
    """``m`` for strict JSON: an undefined figure (R² of a straight run) is None."""
    return {
        k: (None if isinstance(v, float) and not math.isfinite(v) else v)
        for k, v in asdict(m).items()
    }


def json_ready(value: Any) -> Any:
    """``value`` for strict JSON: every non-finite float (at any depth) becomes None."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_ready(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(v) for v in value]
    return value


def metrics_deg(estimate_rad: FloatArray, reference_rad: FloatArray) -> Metrics:
    """Metrics over the samples where estimate and reference are finite: an estimator
    that gives none for some samples (a filter below its speed, a NaN in a bag) is
    scored where it gives one, and the rest is counted, never averaged in."""
    est, ref = np.degrees(estimate_rad), np.degrees(reference_rad)
    finite = np.isfinite(est) & np.isfinite(ref)
    excluded = int(finite.size - np.count_nonzero(finite))
    if not finite.any():
        return Metrics(math.nan, math.nan, math.nan, math.nan, 0, excluded)
    est, ref = est[finite], ref[finite]
    err = est - ref
    ss_tot = float(np.sum((ref - ref.mean()) ** 2))
    r2 = 1.0 - float(np.sum(err**2)) / ss_tot if ss_tot > 0 else math.nan
    return Metrics(
        mae=float(np.mean(np.abs(err))),
        me=float(np.mean(err)),
        rmse=float(np.sqrt(np.mean(err**2))),
        r2=r2,
        n=int(err.size),
        excluded=excluded,
    )


@dataclass(frozen=True)
class Trace:
    """One estimator on one run: β̂ and β [rad] at times t [s] from the run's start."""

    scenario: str
    estimator: str
    t_s: FloatArray
    estimate_rad: FloatArray
    reference_rad: FloatArray
    sigma_rad: FloatArray | None = None
    """The published standard deviation per sample (models with an uncertainty model)."""

    @property
    def metrics(self) -> Metrics:
        return metrics_deg(self.estimate_rad, self.reference_rad)

    @property
    def coverage(self) -> float:
        """Share of the scored samples whose reference is within ±1.96 σ (NaN without σ)."""
        return interval_coverage([self])


def interval_coverage(traces: Sequence[Trace], z: float = Z_95) -> float:
    """Share of samples, over ``traces``, with |β̂ − β| ≤ z·σ (NaN when none has σ)."""
    inside = total = 0
    for t in traces:
        if t.sigma_rad is None:
            continue
        ok = np.isfinite(t.estimate_rad) & np.isfinite(t.reference_rad) & np.isfinite(t.sigma_rad)
        err = np.abs(t.estimate_rad - t.reference_rad)[ok]
        inside += int(np.count_nonzero(err <= z * t.sigma_rad[ok]))
        total += int(err.size)
    return inside / total if total else math.nan


def model_label(meta: ModelMetadata) -> str:
    """Paper naming: LSTM, PSO-LSTM, BiLSTM, PSO-BiLSTM (×N for N merged networks, +
    input set when not paper, + the prior it is a residual on)."""
    arch = "LSTM" if meta.architecture == "lstm" else "BiLSTM"
    label = f"PSO-{arch}" if meta.pso else arch
    merged = meta.provenance.get("merged")
    if isinstance(merged, list):  # sideslip-merge: the mean of several networks
        label += f"×{len(merged)}"
    named = [n for n, inputs in INPUT_SETS.items() if tuple(meta.features) == inputs]
    if not named:
        label += f" [{len(meta.features)} inputs]"
    elif named[0] != "paper":
        label += f" [{named[0]}]"
    if meta.prior != "none":
        label += f" + {meta.prior} prior"
    return label


def predict_run(
    model: SideslipNet,
    meta: ModelMetadata,
    run: Run,
    *,
    vehicle: VehicleDescription | None = None,
    observer_params_file: str | None = None,
    outside_fleet: str = "auto",
    car: str = "recorded",
    mirror_average: bool | str = False,
) -> FloatArray:
    """β̂ [rad] for every sample with a full window, i.e. samples[window-1:] (NaN where
    an input is not finite, e.g. the UKF observer gives no estimate below its speed).

    ``vehicle``: the car, for a model that reads it, when the run's bag records none
    (default: the bag's, else the one stored in the model); ``observer_params_file``:
    the car's ``ukf`` params file, for a model that reads the UKF observer, when the
    run's bag records no car. ``outside_fleet``: as the estimator's parameter, for a car
    outside the model's training cars (:func:`outside_training_cars`): with ``prior``
    (``auto`` for a residual on the UKF) the prior alone is β̂, as the node publishes it.
    ``car``: where the car's parameters come from for runs whose bags record one
    (:data:`~sideslip_training.inputs.CAR_SOURCES`). ``mirror_average``: the network
    averaged with its mirror image, as the node's ``pso_lstm.mirror_average`` (a bool, or
    ``auto`` / ``yes`` / ``no``: :func:`~sideslip_msgs_py.data_source.mirror_average_on`).
    """
    fallback = vehicle
    if fallback is None and meta.vehicle is not None:
        fallback = VehicleDescription.from_mapping(meta.vehicle)
    spec = InputSpec(
        meta.features,
        meta.prior,
        meta.dt_s,
        fallback,
        meta.observer,
        observer_params_file,
        car=car,
    )
    w = meta.window_steps
    if outside_training_cars(meta, run, observer_params_file, car) and publishes_prior(
        outside_fleet, meta.prior
    ):
        # As the node: the prior alone, and the network is not run.
        prior_only = spec.prior_rad(run, w)[w - 1 :]
        return np.where(np.isfinite(prior_only), prior_only, np.nan)
    # The contract's z-score (float64, rounded once to float32), as the estimator does.
    raw = spec.inputs(run)
    x = zscore(raw, meta.feature_mean, meta.feature_std)
    out = _network_output(model, x, w)
    # The node's pso_lstm.mirror_average (sideslip_estimator.mirror_average).
    if mirror_average_on(mirror_average, meta.provenance):
        mirror = zscore(raw * input_signs(meta.features), meta.feature_mean, meta.feature_std)
        out = 0.5 * (out - _network_output(model, mirror, w)) - meta.beta_mean / meta.beta_std
    prior = spec.prior_rad(run, w)[w - 1 :]
    # A window with a non-finite input gives no estimate (as in training and the node).
    bad = np.concatenate([[0], np.cumsum(~np.isfinite(x).all(axis=1))])
    clean = bad[w:] - bad[:-w] == 0
    return np.where(clean, out * meta.beta_std + meta.beta_mean + prior, np.nan)


def _network_output(model: SideslipNet, x: FloatArray, w: int) -> FloatArray:
    """The network's z-scored output y for every full window of the rows ``x``."""
    windows = np.lib.stride_tricks.sliding_window_view(x, w, axis=0)  # (N, F, w)
    out = np.empty(windows.shape[0])
    model.eval()
    with torch.inference_mode():
        for start in range(0, windows.shape[0], PREDICT_BATCH):
            # A copy always: a view that happens to be contiguous is read-only for torch.
            chunk = np.array(windows[start : start + PREDICT_BATCH].transpose(0, 2, 1), order="C")
            out[start : start + chunk.shape[0]] = model(torch.from_numpy(chunk)).numpy()
    return out


def outside_training_cars(
    meta: ModelMetadata,
    run: Run,
    observer_params_file: str | None = None,
    car: str = "recorded",
) -> list[str]:
    """What of the run's car lies outside the model's training cars (one line per
    quantity, :mod:`sideslip_msgs_py.fleet_envelope`); empty when inside or when the
    model records no envelope or reads no UKF observer."""
    if meta.envelope is None or not meta.needs_observer:
        return []
    from .observer import run_params

    params = run_params(run, observer_params_file, car=car)[0]
    return FleetEnvelope.from_dict(meta.envelope).outside(params, run.name)


def kinematic(run: Run, smoothing_steps: int, window_steps: int) -> FloatArray:
    """atan2 of the causal moving average of (X_v, Y_v) over ``smoothing_steps``, for
    samples[window_steps-1:] (the same samples the networks are scored on)."""
    s = run.samples
    kernel = np.ones(smoothing_steps) / smoothing_steps

    def causal_mean(v: FloatArray) -> FloatArray:
        padded = np.concatenate([np.full(smoothing_steps - 1, v[0]), v])
        return np.convolve(padded, kernel, mode="valid")

    beta = np.arctan2(causal_mean(s.y_v_mps), causal_mean(s.x_v_mps))
    return beta[window_steps - 1 :]


def evaluate_runs(
    runs: Sequence[Run],
    models: Sequence[tuple[str, SideslipNet, ModelMetadata]],
    *,
    window_steps: int,
    smoothing_steps: int = 20,
    dt_s: float = STEP_S,
    vehicle: VehicleDescription | None = None,
    observer_params_file: str | None = None,
    car: str = "recorded",
    filters: Mapping[str, str] | None = None,
    beyond_fit_range: str = "auto",
    mirror_average: bool | str = False,
) -> list[Trace]:
    """Traces of every estimator on every run: baselines first (β = 0, kinematic raw and
    smoothed, then the physics ``filters``: back-end name → params file), then the models
    (``vehicle``, ``observer_params_file``: the car of runs whose bags record none, for
    models that read it; ``car``: where the cars come from; see :func:`predict_run`).

    ``beyond_fit_range``: as the estimator's parameter: a model fine-tuned on one car's
    recordings publishes, while its window reaches beyond their range, the estimate and
    σ of the shipped model it started from (``auto``: when the recordings were gentle
    and that model is shipped with the same training data; ``start``: always, requiring
    it), or its own (``model``). ``mirror_average``: every model (and start model)
    averaged with its mirror image, as the estimator's parameter (``auto``: each model
    by its own record of its training data)."""
    car_kwargs = {"vehicle": vehicle, "observer_params_file": observer_params_file, "car": car}
    car_kwargs["mirror_average"] = mirror_average
    starts = {name: start_of(meta, beyond_fit_range, name) for name, _, meta in models}
    if beyond_fit_range == "start" and not any(starts.values()):
        raise StartModelError("--beyond-fit-range start: no model records a range of recordings")
    traces = []
    for run in runs:
        ref = run.samples.beta_rad()[window_steps - 1 :]
        t = np.arange(ref.size) * dt_s + (window_steps - 1) * dt_s
        estimators = [
            ("β = 0", np.zeros(ref.size)),
            ("Kinematic (raw)", kinematic(run, 1, window_steps)),
            (
                f"Kinematic ({smoothing_steps}-step mean)",
                kinematic(run, smoothing_steps, window_steps),
            ),
        ]
        for backend, params_file in (filters or {}).items():
            estimators.append(
                (FILTER_LABELS[backend], physics_filter(run, backend, params_file, window_steps))
            )
        sigmas: dict[str, FloatArray] = {}
        s = run.samples
        for name, model, meta in models:
            if meta.window_steps != window_steps:
                raise ValueError(f"{name}: window {meta.window_steps} != {window_steps}")
            est = predict_run(model, meta, run, **car_kwargs)
            var = None
            unc = published_uncertainty(meta, run, observer_params_file, car)
            if unc is not None:
                var = unc.variance(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)[window_steps - 1 :]
            start = starts[name]
            if start is not None:
                # As the node: beyond the recordings' range the start model's estimate
                # and σ, where this model has an estimate at all.
                start_net, start_meta = start
                fit = Uncertainty.from_dict(meta.uncertainty).fit_range
                assert fit is not None and start_meta.uncertainty is not None
                flags = fit.window_beyond(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)
                gate = flags[window_steps - 1 :] & np.isfinite(est)
                # The start model reads the car the fitted one reads (the node's too).
                start_car = {**car_kwargs}
                if vehicle is None and meta.vehicle is not None:
                    start_car["vehicle"] = VehicleDescription.from_mapping(meta.vehicle)
                est = np.where(gate, predict_run(start_net, start_meta, run, **start_car), est)
                start_unc = published_uncertainty(start_meta, run, observer_params_file, car)
                assert start_unc is not None
                start_var = start_unc.variance(s.x_v_mps, s.y_a_mps2, s.yaw_rate_radps)[
                    window_steps - 1 :
                ]
                var = np.where(gate, start_var, var)
            estimators.append((name, est))
            if var is not None:
                sigmas[name] = np.sqrt(var)
        for name, est in estimators:
            traces.append(Trace(run.name, name, t, est, ref, sigmas.get(name)))
    return traces


def published_uncertainty(
    meta: ModelMetadata, run: Run, observer_params_file: str | None, car: str
) -> Uncertainty | None:
    """The σ model the node publishes for ``meta`` on ``run``'s car (None without one):
    for a model that reads the UKF and stores a σ for described car files, that one
    where the run's UKF file was made from a description (``axles_from``)."""
    if meta.uncertainty is None:
        return None
    unc = Uncertainty.from_dict(meta.uncertainty)
    if unc.described is None or not meta.needs_observer:
        return unc
    from .observer import axles_from

    return unc.for_axles(axles_from(run, observer_params_file, car=car))


class StartModelError(ValueError):
    """``beyond_fit_range`` asks for a start model that cannot be had."""


def start_of(meta: ModelMetadata, mode: str, name: str) -> tuple[SideslipNet, ModelMetadata] | None:
    """The start model a fine-tuned model's estimate falls back to beyond its
    recordings' range (``beyond_fit_range``: see :func:`evaluate_runs`), or None.

    Raises StartModelError for an unknown mode, or for ``start`` when the model records
    a range but its start model is not shipped with the same training data. (Where the
    node would publish the start model's UKF alone, a car outside its training cars, the
    estimate here is the same but σ is the start model's, not the UKF's.)"""
    from sideslip_estimator.backends.model_files import (
        BEYOND_FIT_RANGE,
        hands_over,
        start_model_name,
    )

    from .export import load_model
    from .init_model import resolve

    if mode not in BEYOND_FIT_RANGE:
        raise StartModelError(f"beyond_fit_range must be one of {BEYOND_FIT_RANGE}, got {mode!r}")
    fit = None if meta.uncertainty is None else Uncertainty.from_dict(meta.uncertainty).fit_range
    if not hands_over(mode, fit):
        return None
    start = start_model_name(meta)
    if mode == "start" and start is None:
        raise StartModelError(
            f"{name}: --beyond-fit-range start, but the model names no shipped start model "
            f"with its training data ({meta.provenance.get('init', 'none')})"
        )
    return None if start is None else load_model(resolve(start))


def pooled(traces: Sequence[Trace]) -> dict[str, Metrics]:
    """Per estimator, the metrics over the samples of every run together (sample-
    weighted: a 5-s straight stretch weighs as little as its samples)."""
    out = {}
    for name in dict.fromkeys(t.estimator for t in traces):
        mine = [t for t in traces if t.estimator == name]
        out[name] = metrics_deg(
            np.concatenate([t.estimate_rad for t in mine]),
            np.concatenate([t.reference_rad for t in mine]),
        )
    return out
