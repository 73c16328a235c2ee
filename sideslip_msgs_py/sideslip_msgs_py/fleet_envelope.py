"""The range of cars a model was trained on, and whether a deployed car lies inside it.

A network that corrects a physics filter learnt its corrections on the cars of its
training data; on a car unlike any of them it corrects by guesswork (measured:
``fleet_ukf_measurable``, trained on a fleet with 39-65 % of the weight on the front
axle, was 4× worse than its own UKF prior on ``paper_sedan``'s 74 %). The envelope is
the per-quantity [min, max] over the training cars of a few numbers that describe how a
car turns, all computed from the car's ``ukf`` params file (which every model that reads
the observer gets at deployment):

==========================  ===========================================================
``mass_kg``                 m [kg]
``wheelbase_m``             l = a + b [m]
``front_weight_fraction``   b / l: the share of the weight on the front axle [-]
``cg_height_m``             h [m]
``yaw_dynamic_index``       I_z / (m·a·b) [-]
``steering_ratio_m_per_rad``  rack travel per road-wheel angle [m/rad]
``front_stiffness_per_load``  B·C·μ_peak of the front axle: cornering stiffness over
                            axle load [1/rad]
``rear_stiffness_per_load``   the same, rear axle [1/rad]
``front_peak_friction``     μ_peak of the front axle's fit [-]
``rear_peak_friction``      μ_peak of the rear axle's fit [-]
==========================  ===========================================================

A car is inside when every quantity lies within the training range widened by
:data:`MARGIN` of its width on each side, chosen on the validation fleet as the
smallest of 0.1, 0.15 and 0.2 with which none of its 25 cars falls outside the range
of the 100 training cars: 0.1 did until the ``ukf`` files carried effective axle
characteristics (2026-12-02), whose peak frictions also fold in each car's load
transfer; then one high-CG car with eco tyres (effective front peak 0.70 against the
training cars' 0.75-1.02) fell outside, and on its runs ``fleet_ukf_measurable``'s
network beat the UKF alone on 3 of 4 (0.085° against 0.157°, 0.158° against 0.411° on
the sine steers). The widened range still excludes cars whose weight split no training
car had (``paper_sedan``'s 74 % against the fleet's 39-65 %).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Final

QUANTITIES: Final = (
    "mass_kg",
    "wheelbase_m",
    "front_weight_fraction",
    "cg_height_m",
    "yaw_dynamic_index",
    "steering_ratio_m_per_rad",
    "front_stiffness_per_load",
    "rear_stiffness_per_load",
    "front_peak_friction",
    "rear_peak_friction",
)
MARGIN: Final = 0.2
"""Widening of each training range, as a fraction of its width, on each side."""
OUTSIDE_FLEET: Final = ("auto", "prior", "network", "refuse")
"""What to do with a car outside the envelope (the estimator's ``pso_lstm.outside_fleet``):
publish the model's prior alone (for a residual on the UKF: the UKF's own estimate), the
network's estimate, or refuse; ``auto`` is ``prior`` for a residual on the UKF and
``network`` otherwise."""
_PARAMS_KEYS: Final = (
    "mass_kg",
    "yaw_inertia_kgm2",
    "cg_to_front_axle_m",
    "cg_to_rear_axle_m",
    "cg_height_m",
    "stl_per_road_wheel_angle_m_per_rad",
    "mf_b_front",
    "mf_c_front",
    "mu_peak_front",
    "mf_b_rear",
    "mf_c_rear",
    "mu_peak_rear",
)


def publishes_prior(mode: str, prior: str) -> bool:
    """Whether a model with ``prior`` answers with its prior alone on a car outside its
    envelope under ``mode`` (:data:`OUTSIDE_FLEET`; ``refuse`` answers nothing; a model
    without a prior has nothing else to answer with)."""
    if mode not in OUTSIDE_FLEET:
        raise EnvelopeError(f"outside_fleet must be one of {OUTSIDE_FLEET}, got {mode!r}")
    return prior != "none" and (mode == "prior" or (mode == "auto" and prior == "ukf"))


def _is_number(v: object) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool)


class EnvelopeError(ValueError):
    """An envelope or a params mapping that cannot be used (the message names the key)."""


def quantities_of(ukf_params: Mapping[str, Any], where: str = "ukf params") -> dict[str, float]:
    """The :data:`QUANTITIES` of a car from its ``ukf`` params file contents."""
    values: dict[str, float] = {}
    for key in _PARAMS_KEYS:
        v = ukf_params.get(key)
        if not _is_number(v) or not math.isfinite(v) or v <= 0:
            raise EnvelopeError(f"{where}: {key} must be a number > 0, got {v!r}")
        values[key] = float(v)
    a, b, m = values["cg_to_front_axle_m"], values["cg_to_rear_axle_m"], values["mass_kg"]
    v = values
    return {
        "mass_kg": m,
        "wheelbase_m": a + b,
        "front_weight_fraction": b / (a + b),
        "cg_height_m": values["cg_height_m"],
        "yaw_dynamic_index": values["yaw_inertia_kgm2"] / (m * a * b),
        "steering_ratio_m_per_rad": values["stl_per_road_wheel_angle_m_per_rad"],
        "front_stiffness_per_load": v["mf_b_front"] * v["mf_c_front"] * v["mu_peak_front"],
        "rear_stiffness_per_load": v["mf_b_rear"] * v["mf_c_rear"] * v["mu_peak_rear"],
        "front_peak_friction": values["mu_peak_front"],
        "rear_peak_friction": values["mu_peak_rear"],
    }


@dataclass(frozen=True)
class FleetEnvelope:
    """Per-quantity [min, max] over a model's training cars (see the module docstring)."""

    bounds: Mapping[str, tuple[float, float]]
    cars: int
    """How many distinct cars the ranges were taken over."""

    def __post_init__(self) -> None:
        if set(self.bounds) != set(QUANTITIES):
            missing = sorted(set(QUANTITIES) - set(self.bounds))
            unknown = sorted(set(self.bounds) - set(QUANTITIES))
            raise EnvelopeError(f"envelope: missing {missing}, unknown {unknown}")
        for name, pair in self.bounds.items():
            lo, hi = pair
            if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
                raise EnvelopeError(f"envelope: {name} needs finite min <= max, got {pair!r}")
        if isinstance(self.cars, bool) or not isinstance(self.cars, int) or self.cars < 1:
            raise EnvelopeError(f"envelope: cars must be an integer >= 1, got {self.cars!r}")

    @classmethod
    def of_cars(cls, cars: Iterable[Mapping[str, Any]]) -> FleetEnvelope:
        """The envelope of cars given by their ``ukf`` params (duplicates count once)."""
        distinct = {tuple(sorted(quantities_of(c).items())) for c in cars}
        if not distinct:
            raise EnvelopeError("envelope: no cars")
        rows = [dict(q) for q in distinct]
        bounds = {k: (min(r[k] for r in rows), max(r[k] for r in rows)) for k in QUANTITIES}
        return cls(bounds, len(rows))

    def union(self, other: FleetEnvelope) -> FleetEnvelope:
        """The envelope covering both (a fine-tuned model knows both sets of cars)."""
        a, b = self.bounds, other.bounds
        bounds = {k: (min(a[k][0], b[k][0]), max(a[k][1], b[k][1])) for k in QUANTITIES}
        return FleetEnvelope(bounds, self.cars + other.cars)

    def outside(self, ukf_params: Mapping[str, Any], where: str = "ukf params") -> list[str]:
        """What of the car lies outside the widened ranges, one line per quantity; empty
        when the car is inside."""
        found = []
        for name, value in quantities_of(ukf_params, where).items():
            lo, hi = self.bounds[name]
            pad = MARGIN * (hi - lo)
            if not lo - pad <= value <= hi + pad:
                found.append(f"{name} {value:.4g} outside {lo - pad:.4g}..{hi + pad:.4g}")
        return found

    def to_dict(self) -> dict[str, Any]:
        """JSON form (stored as ``ModelMetadata.envelope``)."""
        return {"cars": self.cars, "bounds": {k: list(self.bounds[k]) for k in QUANTITIES}}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> FleetEnvelope:
        """Parse :meth:`to_dict`'s form (:class:`EnvelopeError` naming what is wrong)."""
        if not isinstance(data, Mapping) or set(data) != {"cars", "bounds"}:
            raise EnvelopeError("envelope: needs exactly the keys 'bounds' and 'cars'")
        raw = data["bounds"]
        if not isinstance(raw, Mapping):
            raise EnvelopeError("envelope: bounds must be an object")
        bounds: dict[str, tuple[float, float]] = {}
        for name, pair in raw.items():
            ok = isinstance(pair, list | tuple) and len(pair) == 2
            if not ok or not all(_is_number(v) for v in pair):
                raise EnvelopeError(f"envelope: {name} must be [min, max], got {pair!r}")
            bounds[str(name)] = (float(pair[0]), float(pair[1]))
        return cls(bounds, data["cars"])
