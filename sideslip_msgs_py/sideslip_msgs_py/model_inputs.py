"""What a network reads and what it is anchored on: input columns and physics priors.

Shared by the trainer (over whole runs) and the estimator (over its window), so both
compute the same numbers. numpy only.

Input columns (a model's ``features``) are of three kinds:

* a contract channel (:data:`~.features.CHANNELS`), as measured;
* a derived input: a pointwise function of one sample's channels, chosen to be
  vehicle-invariant (accelerations in g, rates scaled by speed, steering as a road-wheel
  angle) — :data:`DERIVED`; some need the vehicle's nominal parameters;
* a conditioning input ``vehicle.<name>``: one of the car's nominal parameters
  (:class:`~.vehicle_description.VehicleDescription`), constant over a run;
* an observer input ``ukf.<name>`` (:data:`OBSERVER_COLUMNS`): what the estimator's UKF
  reported after each sample, a column the caller computes beside the channels.

A prior is a physics estimate of β over the window; a model with a prior predicts the
residual β − prior, and β̂ = prior + residual (:data:`PRIORS`). A prior of sample T
reads the window's rows T−N+1..T only (the ``ukf`` prior: the observer's β̂ of row T,
itself recursive over everything before), so training (over runs) and the estimator
(over its window) agree.

Units: SI and radians; speeds below :data:`MIN_SPEED_MPS` are floored in the
divisions (the estimator publishes nothing that slow anyway).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Final

import numpy as np
import numpy.typing as npt

from .errors import ContractError
from .features import CHANNELS, FEATURE_SETS
from .vehicle_description import VehicleDescription

FloatArray = npt.NDArray[np.float64]
Columns = Mapping[str, FloatArray]

GRAVITY_MPS2: Final = 9.80665
MIN_SPEED_MPS: Final = 1.0
VEHICLE_PREFIX: Final = "vehicle."
CONDITIONING: Final[tuple[str, ...]] = (
    "vehicle.mass_kg",
    "vehicle.wheelbase_m",
    "vehicle.front_weight_fraction",
    "vehicle.cg_height_m",
    "vehicle.track_m",
    "vehicle.stl_per_road_wheel_angle_m_per_rad",
    "vehicle.tire_rolling_radius_m",
)
"""The nominal parameters a model may be conditioned on (what an owner can look up)."""
OBSERVER_PREFIX: Final = "ukf."
OBSERVER_COLUMNS: Final[tuple[str, ...]] = (
    "ukf.beta_rad",
    "ukf.road_friction",
    "ukf.yaw_rate_innovation_radps",
    "ukf.lateral_acceleration_innovation_mps2",
)
"""Observer inputs: what the estimator's ``ukf`` back-end reports after each sample: its
β̂ [rad], its road-μ estimate [-], and the innovations (measured − predicted before the
update) of the yaw rate [rad/s] and of a_y [m/s²], which show where the car leaves the
filter's model; NaN where it gives none. A recursive filter, not a function of the
window: the caller runs it over the samples and passes these columns with the channels
(the trainer over a run, ``pso_lstm`` beside its window)."""
OBSERVER_CHANNELS: Final[tuple[str, ...]] = (
    "x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m",
)  # fmt: skip
"""The contract channels the ``ukf`` observer reads (the ``measurable`` ones)."""


class ModelInputError(ContractError, ValueError):
    """An unknown input or prior name, or a vehicle-dependent input without a vehicle."""


def _speed(c: Columns) -> FloatArray:
    return np.maximum(c["x_v_mps"], MIN_SPEED_MPS)


@dataclass(frozen=True)
class Derived:
    """A derived input: its unit, the channels it reads, whether it needs the vehicle."""

    unit: str
    channels: tuple[str, ...]
    needs_vehicle: bool
    compute: Callable[[Columns, VehicleDescription | None], FloatArray]


DERIVED: Final[dict[str, Derived]] = {
    # Y_v/X_v: the kinematic tan β of one (noisy) sample.
    "tan_beta_kinematic": Derived(
        "-", ("x_v_mps", "y_v_mps"), False, lambda c, v: c["y_v_mps"] / _speed(c)
    ),
    # β̇ ≈ v̇_y/u = (a_y − u·ψ̇)/u: the kinematic identity, no vehicle model in it.
    "beta_rate_radps": Derived(
        "rad/s",
        ("x_v_mps", "y_a_mps2", "yaw_rate_radps"),
        False,
        lambda c, v: (c["y_a_mps2"] - c["x_v_mps"] * c["yaw_rate_radps"]) / _speed(c),
    ),
    "x_a_g": Derived("g", ("x_a_mps2",), False, lambda c, v: c["x_a_mps2"] / GRAVITY_MPS2),
    "y_a_g": Derived("g", ("y_a_mps2",), False, lambda c, v: c["y_a_mps2"] / GRAVITY_MPS2),
    # u·ψ̇: the centripetal acceleration of the path, in g.
    "centripetal_g": Derived(
        "g",
        ("x_v_mps", "yaw_rate_radps"),
        False,
        lambda c, v: c["x_v_mps"] * c["yaw_rate_radps"] / GRAVITY_MPS2,
    ),
    # δ = STL / steering ratio: the mean road-wheel angle.
    "road_wheel_angle_rad": Derived(
        "rad",
        ("stl_m",),
        True,
        lambda c, v: c["stl_m"] / _vehicle(v).stl_per_road_wheel_angle_m_per_rad,
    ),
    # δ − L·ψ̇/u = α_f − α_r in the single-track model: the understeer angle.
    "understeer_angle_rad": Derived(
        "rad",
        ("x_v_mps", "yaw_rate_radps", "stl_m"),
        True,
        lambda c, v: (
            c["stl_m"] / _vehicle(v).stl_per_road_wheel_angle_m_per_rad
            - _vehicle(v).wheelbase_m * c["yaw_rate_radps"] / _speed(c)
        ),
    ),
    # b·ψ̇/u: β of a rear axle that does not slip (β = b·ψ̇/u − α_r).
    "rear_kinematic_beta_rad": Derived(
        "rad",
        ("x_v_mps", "yaw_rate_radps"),
        True,
        lambda c, v: _vehicle(v).cg_to_rear_axle_m * c["yaw_rate_radps"] / _speed(c),
    ),
}


def _vehicle(v: VehicleDescription | None) -> VehicleDescription:
    if v is None:
        raise ModelInputError("this input needs the vehicle's nominal parameters")
    return v


INPUT_SETS: Final[dict[str, tuple[str, ...]]] = {
    # The feature sets of DESIGN.md, as measured.
    **FEATURE_SETS,
    # Kinematics only: no steering, no vehicle. With the kinematic_window prior the
    # network can only refine what the kinematics say, not learn one car's steering.
    "paper_kinematic": (
        "x_v_mps", "tan_beta_kinematic", "beta_rate_radps", "x_a_g", "y_a_g",
        "yaw_rate_radps",
    ),
    # Kinematics, steering as road-wheel and understeer angles, and the car's nominal
    # parameters: the network can learn how a car's dynamics refine the kinematics.
    "paper_invariant": (
        "x_v_mps", "tan_beta_kinematic", "beta_rate_radps", "x_a_g", "y_a_g",
        "yaw_rate_radps", "road_wheel_angle_rad", "understeer_angle_rad",
        "vehicle.mass_kg", "vehicle.wheelbase_m", "vehicle.front_weight_fraction",
        "vehicle.cg_height_m",
    ),
    # No Y_v: vehicle-invariant scaling plus the car's nominal parameters.
    "measurable_invariant": (
        "x_v_mps", "x_a_g", "y_a_g", "centripetal_g", "beta_rate_radps",
        "road_wheel_angle_rad", "understeer_angle_rad", "rear_kinematic_beta_rad",
        "vehicle.mass_kg", "vehicle.wheelbase_m", "vehicle.front_weight_fraction",
        "vehicle.cg_height_m",
    ),
    # No Y_v, anchored on the UKF: its β̂, μ̂ and innovations beside the
    # measurable_invariant inputs, for a residual on the ukf prior (the network corrects
    # what the observer's model misses, which its innovations show).
    "measurable_observer": (
        "x_v_mps", "x_a_g", "y_a_g", "centripetal_g", "beta_rate_radps",
        "road_wheel_angle_rad", "understeer_angle_rad", "rear_kinematic_beta_rad",
        *OBSERVER_COLUMNS,
        "vehicle.mass_kg", "vehicle.wheelbase_m", "vehicle.front_weight_fraction",
        "vehicle.cg_height_m",
    ),
    # measurable_observer without the car's parameters: the filter already has them,
    # and a network that reads them can be led astray by a car outside the fleet.
    "measurable_observer_signals": (
        "x_v_mps", "x_a_g", "y_a_g", "centripetal_g", "beta_rate_radps",
        "road_wheel_angle_rad", "understeer_angle_rad", "rear_kinematic_beta_rad",
        *OBSERVER_COLUMNS,
    ),
    # Kinematics plus the UKF observer's β̂ and μ̂: two independent physics estimates
    # (Y_v's and the car model's) for the network to weigh.
    "paper_observer": (
        "x_v_mps", "tan_beta_kinematic", "beta_rate_radps", "x_a_g", "y_a_g",
        "yaw_rate_radps", "ukf.beta_rad", "ukf.road_friction",
    ),
}  # fmt: skip
"""Named input sets for ``sideslip-train --features``."""


def input_set(name: str) -> tuple[str, ...]:
    try:
        return INPUT_SETS[name]
    except KeyError:
        msg = f"unknown input set {name!r} (known: {', '.join(INPUT_SETS)})"
        raise ModelInputError(msg) from None


def check_inputs(names: Sequence[str]) -> tuple[str, ...]:
    """``names`` as a tuple, each a channel, a derived input or a conditioning input."""
    names = tuple(names)
    known = set(CHANNELS) | set(DERIVED) | set(CONDITIONING) | set(OBSERVER_COLUMNS)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise ModelInputError(
            f"unknown model input(s) {unknown} (channels: {', '.join(CHANNELS)}; derived: "
            f"{', '.join(DERIVED)}; conditioning: {', '.join(CONDITIONING)}; observer: "
            f"{', '.join(OBSERVER_COLUMNS)})"
        )
    if len(set(names)) != len(names):
        raise ModelInputError(f"model inputs have duplicates: {list(names)}")
    return names


def needs_observer(names: Sequence[str], prior: str = "none") -> bool:
    """Whether these inputs (or this prior) read the UKF observer's columns."""
    return any(n in OBSERVER_COLUMNS for n in names) or PRIORS[prior].needs_observer


def _observer_column(c: Columns, name: str) -> FloatArray:
    try:
        return c[name]
    except KeyError:
        msg = f"{name} is the UKF observer's output: pass its column with the channels"
        raise ModelInputError(msg) from None


def needs_vehicle(names: Sequence[str], prior: str = "none") -> bool:
    """Whether these inputs (or this prior) read the vehicle's nominal parameters."""
    return (
        any(n.startswith(VEHICLE_PREFIX) for n in names)
        or any(n in DERIVED and DERIVED[n].needs_vehicle for n in names)
        or PRIORS[prior].needs_vehicle
    )


def required_channels(names: Sequence[str], prior: str = "none") -> tuple[str, ...]:
    """The contract channels these inputs and this prior read, in CHANNELS order."""
    used: set[str] = set(PRIORS[prior].channels)
    for n in check_inputs(names):
        if n in CHANNELS:
            used.add(n)
        elif n in DERIVED:
            used.update(DERIVED[n].channels)
        elif n in OBSERVER_COLUMNS:
            used.update(OBSERVER_CHANNELS)
    return tuple(c for c in CHANNELS if c in used)


def input_matrix(
    columns: Columns, names: Sequence[str], vehicle: VehicleDescription | None = None
) -> FloatArray:
    """(S, F) float64 model inputs from per-sample channel columns (each shape (S,))."""
    names = check_inputs(names)
    length = len(next(iter(columns.values())))
    out = np.empty((length, len(names)), dtype=np.float64)
    for j, n in enumerate(names):
        if n in CHANNELS:
            out[:, j] = columns[n]
        elif n in DERIVED:
            out[:, j] = DERIVED[n].compute(columns, vehicle)
        elif n in OBSERVER_COLUMNS:
            out[:, j] = _observer_column(columns, n)
        else:
            out[:, j] = _vehicle(vehicle).value(n.removeprefix(VEHICLE_PREFIX))
    return out


# --- priors ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Prior:
    """A physics estimate of β over a window: the channels it reads, whether it needs
    the vehicle, and ``series(columns, window_steps, dt_s)`` → β_prior [rad] of every
    sample T ≥ window_steps − 1 from rows T−N+1..T (NaN before, except for "none")."""

    description: str
    channels: tuple[str, ...]
    needs_vehicle: bool
    series: Callable[[Columns, int, float], FloatArray]
    needs_observer: bool = False


def _window_mean(v: FloatArray, n: int) -> FloatArray:
    """Mean of v over the n samples ending at each index (NaN for the first n − 1)."""
    out = np.full(v.shape[0], np.nan)
    if v.shape[0] >= n:
        c = np.concatenate([[0.0], np.cumsum(v)])
        out[n - 1 :] = (c[n:] - c[:-n]) / n
    return out


def _dead_reckoned_mean(measured: FloatArray, rate: FloatArray, n: int, dt_s: float) -> FloatArray:
    """Estimate of a velocity at the last sample of each n-window: every sample k of the
    window carried forward to the end by integrating its known rate (rectangle rule),
    v̂(T) = mean_k [v_k + Σ_{j=k}^{T−1} rate_j·dt], the least-squares estimate when the
    measurement noise is white and the rate is exact."""
    integral = np.concatenate([[0.0], np.cumsum(rate * dt_s)])  # I[k] = Σ_{j<k}
    return _window_mean(measured - integral[:-1], n) + integral[:-1]


def _kinematic_window(c: Columns, n: int, dt_s: float) -> FloatArray:
    v_y = _dead_reckoned_mean(
        c["y_v_mps"], c["y_a_mps2"] - c["x_v_mps"] * c["yaw_rate_radps"], n, dt_s
    )
    v_x = _dead_reckoned_mean(c["x_v_mps"], c["x_a_mps2"], n, dt_s)
    return np.arctan2(v_y, v_x)


def _observer_beta(c: Columns, n: int, dt_s: float) -> FloatArray:
    out = np.array(_observer_column(c, "ukf.beta_rad"), dtype=np.float64)
    out[: n - 1] = np.nan
    return out


def _none(c: Columns, n: int, dt_s: float) -> FloatArray:
    return np.zeros(len(next(iter(c.values()))))


PRIORS: Final[dict[str, Prior]] = {
    "none": Prior("no prior: the network predicts β itself", (), False, _none),
    "kinematic_window": Prior(
        "atan2 of the window's dead-reckoned mean velocity: each (X_v, Y_v) sample carried "
        "to the window's end with v̇_y = a_y − X_v·ψ̇ and v̇_x = a_x (vehicle-independent; "
        "needs Y_v)",
        ("x_v_mps", "y_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps"),
        False,
        _kinematic_window,
    ),
    "ukf": Prior(
        "the UKF observer's β̂ at the window's last sample (the estimator's ukf back-end "
        "with the car's nominal parameters; measurable channels only, no Y_v)",
        OBSERVER_CHANNELS,
        False,  # the car reaches the filter through its own params file
        _observer_beta,
        needs_observer=True,
    ),
}


def check_prior(name: str) -> str:
    if name not in PRIORS:
        raise ModelInputError(f"unknown prior {name!r} (known: {', '.join(PRIORS)})")
    return name


def prior_series(columns: Columns, prior: str, window_steps: int, dt_s: float) -> FloatArray:
    """β_prior [rad] of every sample (NaN for the first window_steps − 1)."""
    return PRIORS[check_prior(prior)].series(columns, window_steps, dt_s)


def prior_of_window(columns: Columns, prior: str, dt_s: float) -> float:
    """β_prior [rad] at the last row of one window (columns hold exactly its rows)."""
    n = len(next(iter(columns.values())))
    value = float(PRIORS[check_prior(prior)].series(columns, n, dt_s)[-1])
    return value if math.isfinite(value) else math.nan


def columns_of(obj: object, channels: Sequence[str]) -> dict[str, FloatArray]:
    """Channel columns of anything with one array attribute per channel (SampleArrays)."""
    return {c: np.asarray(getattr(obj, c), dtype=np.float64) for c in channels}


def columns_of_rows(rows: FloatArray, channels: Sequence[str]) -> dict[str, FloatArray]:
    """Channel columns of estimator window rows (columns in CHANNELS order)."""
    return {c: rows[:, CHANNELS.index(c)] for c in channels}


__all__ = [
    "CONDITIONING",
    "DERIVED",
    "INPUT_SETS",
    "OBSERVER_CHANNELS",
    "OBSERVER_COLUMNS",
    "PRIORS",
    "ModelInputError",
    "check_inputs",
    "check_prior",
    "columns_of",
    "columns_of_rows",
    "input_matrix",
    "input_set",
    "needs_observer",
    "needs_vehicle",
    "prior_of_window",
    "prior_series",
    "required_channels",
]
