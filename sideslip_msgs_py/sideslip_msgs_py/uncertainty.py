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
"""

from __future__ import annotations

import math
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


class UncertaintyError(ValueError):
    """An uncertainty model that cannot be used (the message names the field)."""


def terms(
    x_v_mps: npt.ArrayLike, y_a_mps2: npt.ArrayLike, yaw_rate_radps: npt.ArrayLike
) -> npt.NDArray[np.float64]:
    """The model's terms per sample, shape (n, 4) in :data:`TERMS` order."""
    v = np.maximum(np.asarray(x_v_mps, dtype=np.float64), MIN_SPEED_MPS)
    a_y = np.asarray(y_a_mps2, dtype=np.float64)
    beta_rate = a_y / v - np.asarray(yaw_rate_radps, dtype=np.float64)
    return np.stack([np.ones_like(v), 1.0 / v**2, a_y**2, beta_rate**2], axis=-1)


@dataclass(frozen=True)
class Uncertainty:
    """σ² = scale² · Σ coefficients · :func:`terms` (rad²); see the module docstring."""

    coefficients: tuple[float, ...]
    scale: float
    coverage: float = 0.95
    """The share of calibration samples within ±1.96 σ that ``scale`` was chosen for."""
    kind: str = KIND

    def __post_init__(self) -> None:
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

    def variance(
        self, x_v_mps: npt.ArrayLike, y_a_mps2: npt.ArrayLike, yaw_rate_radps: npt.ArrayLike
    ) -> npt.NDArray[np.float64]:
        """σ² [rad²] per sample."""
        t = terms(x_v_mps, y_a_mps2, yaw_rate_radps)
        return self.scale**2 * (t @ np.asarray(self.coefficients))

    def variance_of(self, x_v_mps: float, y_a_mps2: float, yaw_rate_radps: float) -> float:
        """σ² [rad²] of one sample (the estimator's path: plain floats, no arrays)."""
        v = max(x_v_mps, MIN_SPEED_MPS)
        beta_rate = y_a_mps2 / v - yaw_rate_radps
        c0, c1, c2, c3 = self.coefficients
        return self.scale**2 * (c0 + c1 / (v * v) + c2 * y_a_mps2**2 + c3 * beta_rate**2)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "terms": list(TERMS),
            "coefficients": list(self.coefficients),
            "scale": self.scale,
            "coverage": self.coverage,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Uncertainty:
        if not isinstance(data, Mapping):
            raise UncertaintyError(f"uncertainty must be a JSON object, got {type(data).__name__}")
        unknown = set(data) - {"kind", "terms", "coefficients", "scale", "coverage"}
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
            )
        except (KeyError, TypeError) as err:
            raise UncertaintyError(f"uncertainty: missing or malformed {err}") from None
