"""The standard deviation published with each β̂: a variance that follows the driving.

A constant (the validation RMSE²) is too wide on a straight at speed and too narrow at
walking pace or at the limit: measured on the fleet validation set, its nominal 95 %
interval covered 62 % of one run and 99 % of the median one. The model here is

    σ² = s² · (c₀ + c₁ / X_v² + c₂ · a_y² + c₃ · β̇²),  β̇ ≈ a_y / X_v − ψ̇,

with X_v [m/s] floored at 1 m/s, a_y [m/s²] and ψ̇ [rad/s] of the estimated sample: the
kinematic part of the error shrinks with speed (the velocity noise over X_v), the
dynamic part grows with lateral acceleration and sideslip rate. The coefficients
c ≥ 0 are fitted by Gaussian likelihood on validation data and ``s`` is a conformal
scale from other validation bags, so that the interval ±1.96 σ holds 95 % of their
samples (``sideslip-calibrate``). Stored in the model file (``ModelMetadata.uncertainty``)
and evaluated per sample by the estimator.

A model fine-tuned on one car's recordings may carry a :class:`FitRange`: the range of
lateral acceleration and sideslip rate its recordings covered. Its scale, fitted on those
recordings, holds inside that range; while the input window reaches beyond it (a limit
manoeuvre the recordings lack) the network extrapolates, and the larger
``outside_scale`` is used instead (``sideslip-train`` sets it from the start model's
fleet scale).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

KIND: Final = "speed_acceleration_v1"
TERMS: Final = (
    "constant",
    "inverse_speed_squared",
    "lateral_acceleration_squared",
    "beta_rate_squared",
)
MIN_SPEED_MPS: Final = 1.0
Z_95: Final = 1.959963984540054
FIT_RANGE_QUANTILE: Final = 0.999
"""The share of a car's samples a :class:`FitRange` spans: the largest values are single
noise spikes (the paper's a_y noise alone has σ 0.1 m/s² per sample), not driving."""


class UncertaintyError(ValueError):
    """An uncertainty model that cannot be used (the message names the field)."""


def _beta_rate(
    v: npt.NDArray[np.float64], a_y: npt.ArrayLike, r: npt.ArrayLike
) -> npt.NDArray[np.float64]:
    """β̇ ≈ a_y / X_v − ψ̇ [rad/s] (X_v already floored)."""
    return np.asarray(a_y, dtype=np.float64) / v - np.asarray(r, dtype=np.float64)


def terms(
    x_v_mps: npt.ArrayLike, y_a_mps2: npt.ArrayLike, yaw_rate_radps: npt.ArrayLike
) -> npt.NDArray[np.float64]:
    """The model's terms per sample, shape (n, 4) in :data:`TERMS` order."""
    v = np.maximum(np.asarray(x_v_mps, dtype=np.float64), MIN_SPEED_MPS)
    a_y = np.asarray(y_a_mps2, dtype=np.float64)
    beta_rate = _beta_rate(v, a_y, yaw_rate_radps)
    return np.stack([np.ones_like(v), 1.0 / v**2, a_y**2, beta_rate**2], axis=-1)


GENTLE_LATERAL_MPS2: Final = 5.0
"""Recordings whose lateral range stays under this [m/s², about 0.5 g] are gentle: a
model fine-tuned on them forgets the limit its start model knew (docs/evaluation/
fit-bags, "Gentle recordings"), so the node hands over to the start model beyond them
(``pso_lstm.beyond_fit_range`` auto); fits on driving beyond it keep their own estimate."""


@dataclass(frozen=True)
class FitRange:
    """The driving a fine-tuned model's scale was fitted on: |a_y| ≤
    ``lateral_acceleration_mps2`` [m/s²] and |β̇| ≤ ``beta_rate_radps`` [rad/s]
    (β̇ ≈ a_y / X_v − ψ̇, as in :func:`terms`). While any sample of the network's input
    window (the last ``window_steps``) lies beyond it, σ takes ``outside_scale`` when
    that is the larger: the network's error outlives the sample that caused it."""

    lateral_acceleration_mps2: float
    beta_rate_radps: float
    outside_scale: float
    window_steps: int = 1

    def __post_init__(self) -> None:
        for name, least in (
            ("lateral_acceleration_mps2", ">= 0"),
            ("beta_rate_radps", ">= 0"),
            ("outside_scale", "> 0"),
        ):
            value = getattr(self, name)
            ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
            ok = ok and math.isfinite(value)
            if not (ok and (value > 0.0 or (value == 0.0 and least == ">= 0"))):
                raise UncertaintyError(f"uncertainty.fit_range: {name} must be finite and "
                                       f"{least}, got {value!r}")  # fmt: skip
            object.__setattr__(self, name, float(value))
        steps = self.window_steps
        # JSON writers may give 100 as 100.0: an integral number is taken.
        integral = isinstance(steps, numbers.Real) and not isinstance(steps, bool)
        if not (integral and math.isfinite(steps) and float(steps).is_integer() and steps >= 1):
            raise UncertaintyError(
                f"uncertainty.fit_range: window_steps must be an integer >= 1, got {steps!r}"
            )
        object.__setattr__(self, "window_steps", int(steps))

    @classmethod
    def of_samples(
        cls,
        x_v_mps: npt.ArrayLike,
        y_a_mps2: npt.ArrayLike,
        yaw_rate_radps: npt.ArrayLike,
        outside_scale: float,
        window_steps: int,
        quantile: float = FIT_RANGE_QUANTILE,
    ) -> FitRange:
        """The range spanned by the samples at speed (X_v ≥ 1 m/s, where β is a target)."""
        v = np.asarray(x_v_mps, dtype=np.float64)
        a_y = np.asarray(y_a_mps2, dtype=np.float64)
        r = np.asarray(yaw_rate_radps, dtype=np.float64)
        ok = (v >= MIN_SPEED_MPS) & np.isfinite(v) & np.isfinite(a_y) & np.isfinite(r)
        if not ok.any():
            raise UncertaintyError("uncertainty.fit_range: no sample at 1 m/s or more")
        beta_rate = _beta_rate(v[ok], a_y[ok], r[ok])
        return cls(
            float(np.quantile(np.abs(a_y[ok]), quantile)),
            float(np.quantile(np.abs(beta_rate), quantile)),
            outside_scale,
            window_steps,
        )

    def beyond(
        self, x_v_mps: npt.ArrayLike, y_a_mps2: npt.ArrayLike, yaw_rate_radps: npt.ArrayLike
    ) -> npt.NDArray[np.bool_]:
        """Per sample: this sample lies beyond the range."""
        v = np.maximum(np.atleast_1d(np.asarray(x_v_mps, dtype=np.float64)), MIN_SPEED_MPS)
        a_y = np.atleast_1d(np.asarray(y_a_mps2, dtype=np.float64))
        r = np.atleast_1d(np.asarray(yaw_rate_radps, dtype=np.float64))
        return (np.abs(a_y) > self.lateral_acceleration_mps2) | (
            np.abs(_beta_rate(v, a_y, r)) > self.beta_rate_radps
        )

    @property
    def gentle(self) -> bool:
        """The recordings stayed under :data:`GENTLE_LATERAL_MPS2` of |a_y|."""
        return self.lateral_acceleration_mps2 < GENTLE_LATERAL_MPS2

    def reaches_beyond(
        self,
        x_v_mps: npt.NDArray[np.float64],
        y_a_mps2: npt.NDArray[np.float64],
        yaw_rate_radps: npt.NDArray[np.float64],
    ) -> bool:
        """Whether any of the last ``window_steps`` samples (float arrays in time order)
        lies beyond the range: the estimator's per-sample check, without per-sample
        flags (half the time of ``beyond(...).any()`` at 400 Hz)."""
        n = self.window_steps
        a_y = y_a_mps2[-n:]
        if np.abs(a_y).max() > self.lateral_acceleration_mps2:
            return True
        v = np.maximum(x_v_mps[-n:], MIN_SPEED_MPS)
        return bool(np.abs(a_y / v - yaw_rate_radps[-n:]).max() > self.beta_rate_radps)

    def window_beyond(
        self,
        x_v_mps: npt.ArrayLike,
        y_a_mps2: npt.ArrayLike,
        yaw_rate_radps: npt.ArrayLike,
        run: npt.ArrayLike | None = None,
    ) -> npt.NDArray[np.bool_]:
        """Per sample: a sample of its trailing window (``window_steps``, itself
        included) lies beyond the range. Samples are in time order; ``run`` gives each
        sample's run (contiguous ids; the window restarts with each run; default one run)."""
        out = self.beyond(x_v_mps, y_a_mps2, yaw_rate_radps)
        ids = np.zeros(out.size, np.int64) if run is None else np.atleast_1d(np.asarray(run))
        if ids.shape != out.shape:
            raise UncertaintyError(
                f"run must give one id per sample: {ids.size} ids for {out.size} samples"
            )
        starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
        if np.unique(ids[starts]).size != starts.size:
            raise UncertaintyError("run ids must be contiguous: a run's samples in one stretch")
        for a, b in zip(starts, np.r_[starts[1:], out.size], strict=True):
            count = np.concatenate([[0], np.cumsum(out[a:b])])
            k = np.arange(1, b - a + 1)
            out[a:b] = count[k] - count[np.maximum(k - self.window_steps, 0)] > 0
        return out

    def to_dict(self) -> dict[str, float | int]:
        return {
            "lateral_acceleration_mps2": self.lateral_acceleration_mps2,
            "beta_rate_radps": self.beta_rate_radps,
            "outside_scale": self.outside_scale,
            "window_steps": self.window_steps,
        }

    @classmethod
    def from_dict(cls, data: Any) -> FitRange:
        if not isinstance(data, Mapping):
            raise UncertaintyError(
                f"uncertainty.fit_range must be a JSON object, got {type(data).__name__}"
            )
        keys = {"lateral_acceleration_mps2", "beta_rate_radps", "outside_scale", "window_steps"}
        if set(data) != keys:
            raise UncertaintyError(f"uncertainty.fit_range: keys must be {sorted(keys)}, "
                                   f"got {sorted(data)}")  # fmt: skip
        return cls(
            data["lateral_acceleration_mps2"],
            data["beta_rate_radps"],
            data["outside_scale"],
            data["window_steps"],
        )


@dataclass(frozen=True)
class Uncertainty:
    """σ² = scale² · Σ coefficients · :func:`terms` (rad²); see the module docstring."""

    coefficients: tuple[float, ...]
    scale: float
    coverage: float = 0.95
    """The share of calibration samples within ±1.96 σ that ``scale`` was chosen for."""
    kind: str = KIND
    fit_range: FitRange | None = None
    """Where ``scale`` holds, for a model fine-tuned on one car (None: everywhere)."""
    described: Uncertainty | None = None
    """The σ to publish instead when the car's ``ukf`` file was made from a description
    (``axles_from: description``: the fleet's typical tyres, not the car's), for a model
    that reads the UKF: calibrated with such files (``sideslip-calibrate --car
    described``). None: this σ for every file."""

    def __post_init__(self) -> None:
        if self.described is not None and (
            self.described.described is not None or self.described.fit_range is not None
        ):
            raise UncertaintyError(
                "uncertainty.described may not have a described or fit_range of its own"
            )
        if self.described is not None and self.fit_range is not None:
            # A model fitted on one car's recordings reads that car's one file.
            raise UncertaintyError("uncertainty: a σ with a fit_range may not have a described one")
        if self.kind != KIND:
            raise UncertaintyError(f"uncertainty: unknown kind {self.kind!r} (known: {KIND})")
        c = tuple(float(x) for x in self.coefficients)
        if len(c) != len(TERMS) or not all(math.isfinite(x) and x >= 0.0 for x in c):
            raise UncertaintyError(
                f"uncertainty: coefficients must be {len(TERMS)} finite numbers >= 0 "
                f"({', '.join(TERMS)}), got {self.coefficients!r}"
            )
        if sum(c) <= 0.0:
            raise UncertaintyError("uncertainty: all coefficients are 0")
        object.__setattr__(self, "coefficients", c)
        if not (math.isfinite(self.scale) and self.scale > 0.0):
            raise UncertaintyError(f"uncertainty: scale must be finite and > 0, got {self.scale!r}")
        if not 0.0 < self.coverage < 1.0:
            raise UncertaintyError(
                f"uncertainty: coverage must be in (0, 1), got {self.coverage!r}"
            )
        object.__setattr__(self, "scale", float(self.scale))
        object.__setattr__(self, "coverage", float(self.coverage))

    def for_axles(self, axles_from: str) -> Uncertainty:
        """The σ model to publish for a car file whose axle curves come from
        ``axles_from`` (``sideslip_estimator.backends.ukf_model.AXLES_FROM``): the
        :attr:`described` one for ``description`` where there is one, else this."""
        if axles_from == "description" and self.described is not None:
            return self.described
        return self

    def variance(
        self,
        x_v_mps: npt.ArrayLike,
        y_a_mps2: npt.ArrayLike,
        yaw_rate_radps: npt.ArrayLike,
        run: npt.ArrayLike | None = None,
        beyond: npt.ArrayLike | None = None,
    ) -> npt.NDArray[np.float64]:
        """σ² [rad²] per sample. With a :attr:`fit_range` the samples must be in time
        order, ``run`` (contiguous ids) telling runs apart (default: one run); or
        ``beyond`` gives each sample's :meth:`FitRange.window_beyond` flag, computed on
        whole runs, for samples taken out of them (scored samples only)."""
        t = terms(x_v_mps, y_a_mps2, yaw_rate_radps)
        scale: float | npt.NDArray[np.float64] = self.scale
        if self.fit_range is not None:
            if beyond is None:
                beyond = self.fit_range.window_beyond(x_v_mps, y_a_mps2, yaw_rate_radps, run)
            wide = np.reshape(np.asarray(beyond, dtype=bool), np.shape(t)[:-1])
            scale = np.where(wide, max(self.scale, self.fit_range.outside_scale), self.scale)
        return scale**2 * (t @ np.asarray(self.coefficients))

    def variance_of(self, x_v_mps: float, y_a_mps2: float, yaw_rate_radps: float) -> float:
        """σ² [rad²] of one sample with its own scale, whatever :attr:`fit_range` says
        (the estimator's path: plain floats, no arrays; see :meth:`variance_of_window`)."""
        v = max(x_v_mps, MIN_SPEED_MPS)
        beta_rate = y_a_mps2 / v - yaw_rate_radps
        c0, c1, c2, c3 = self.coefficients
        return self.scale**2 * (c0 + c1 / (v * v) + c2 * y_a_mps2**2 + c3 * beta_rate**2)

    def variance_of_window(
        self, x_v_mps: npt.ArrayLike, y_a_mps2: npt.ArrayLike, yaw_rate_radps: npt.ArrayLike
    ) -> tuple[float, bool]:
        """σ² [rad²] of the newest sample of an input window (samples in time order), as
        :meth:`variance_of`, widened while the window reaches beyond :attr:`fit_range`;
        and whether it reaches beyond (False without a range)."""
        v = np.asarray(x_v_mps, dtype=np.float64)
        a_y = np.asarray(y_a_mps2, dtype=np.float64)
        r = np.asarray(yaw_rate_radps, dtype=np.float64)
        var = self.variance_of(float(v[-1]), float(a_y[-1]), float(r[-1]))
        fit = self.fit_range
        if fit is None:
            return var, False
        beyond = fit.reaches_beyond(v, a_y, r)
        if beyond and fit.outside_scale > self.scale:
            var *= (fit.outside_scale / self.scale) ** 2
        return var, beyond

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "kind": self.kind,
            "terms": list(TERMS),
            "coefficients": list(self.coefficients),
            "scale": self.scale,
            "coverage": self.coverage,
        }
        if self.fit_range is not None:
            out["fit_range"] = self.fit_range.to_dict()
        if self.described is not None:
            out["described"] = self.described.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Uncertainty:
        if not isinstance(data, Mapping):
            raise UncertaintyError(f"uncertainty must be a JSON object, got {type(data).__name__}")
        known = {"kind", "terms", "coefficients", "scale", "coverage", "fit_range", "described"}
        unknown = set(data) - known
        if unknown:
            raise UncertaintyError(f"uncertainty: unknown key(s) {sorted(unknown)}")
        if list(data.get("terms", TERMS)) != list(TERMS):
            raise UncertaintyError(f"uncertainty: terms must be {list(TERMS)}")
        try:
            return cls(
                tuple(data["coefficients"]),
                float(data["scale"]),
                float(data.get("coverage", 0.95)),
                str(data.get("kind", KIND)),
                None if data.get("fit_range") is None else FitRange.from_dict(data["fit_range"]),
                None if data.get("described") is None else cls._described_of(data["described"]),
            )
        except (KeyError, TypeError) as err:
            raise UncertaintyError(f"uncertainty: missing or malformed {err}") from None

    @classmethod
    def _described_of(cls, data: Any) -> Uncertainty:
        if not isinstance(data, Mapping):
            raise UncertaintyError(
                f"uncertainty.described must be a JSON object, got {type(data).__name__}"
            )
        try:
            return cls.from_dict(data)
        except UncertaintyError as err:
            msg = str(err).replace("uncertainty", "uncertainty.described", 1)
            raise UncertaintyError(msg) from None
