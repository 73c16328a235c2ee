"""The UKF's model: a nonlinear single-track car with Magic Formula axles, and its file.

Inputs: δ = STL / steering ratio (mean road-wheel angle) and a_x = X_a. Model:

    v̇_x = a_x + ψ̇ v_y
    v̇_y = (F_yf cos δ + F_yr)/m − ψ̇ v_x
    ψ̈   = (a F_yf cos δ − b F_yr)/I_z
    α_f,kin = δ − atan((v_y + a ψ̇)/v_x),   α_r,kin = −atan((v_y − b ψ̇)/v_x)
    α̇_i = (v_x/σ_i)(α_i,kin − α_i)             (tyre lag, σ_i = relaxation length)
    F_yi = μ (F_zi/F_zi0) D_i sin(C_i atan(B_i α_i/μ − E_i (B_i α_i/μ − atan(B_i α_i/μ))))

with D_i = μ_peak,i F_zi0 at the static axle load F_zi0, F_zi the axle load with
longitudinal load transfer (F_zf = m (g b − a_x h)/L, F_zr = m (g a + a_x h)/L), and
α_i = α_i,kin without ``tyre_relaxation``. Road friction enters by similarity, as in the
simulator's tyre model: the peak scales with μ, the slip at the peak too, and the
cornering stiffness B C D does not change, so in the tyres' linear range the model *is*
the linear single-track model (tested) and μ is hardly observable there (it wanders a
little; the memory keeps its uncertainty bounded on long straight drives).
Measurements: ψ̇ (yaw rate), a_y = (F_yf cos δ + F_yr)/m (Y_a) and v_x (X_v).

Why these states (measured before the noise tuning): on the paper-test scenarios (paper
noise) the tyre lag took the MAE from 0.18° to 0.06° (at 80 km/h the front tyres lag by
~20 ms; without it the model's forces lead the car's and the filter reads that as low
friction); estimating μ is what makes low-friction roads and other cars work
(compact_rwd paper-test 0.22° → 0.08°), at a small cost on a dry road where μ = 1 is
exactly right; the longitudinal load transfer: paper_sedan 0.063° → 0.055°. Lateral
load transfer and roll steer are not in the equations: the files ``sideslip_sim.ukf_params``
writes fold them into the axle curves (effective axle characteristics, fitted to the
whole car's steady cornering; the validation fleet's pooled MAE 0.141° → 0.104°). Known
gaps: their dynamics (roll lags the lateral acceleration by a few tenths of a second),
compliance steer, nominal mass and inertia (no payload), and a road that is not level
(gravity's share on a crossfall moves the car but the tyres do not give it: the filter's
optional disturbance state, :mod:`.ukf`, docs/evaluation/road-bank).

:class:`UkfParams` is the vehicle's file (``python -m sideslip_sim.ukf_params VEHICLE``
writes it; shipped ones in ``data/ukf``); :class:`SingleTrackMagicFormula` evaluates the
equations above elementwise: the filter hands it all its sigma points at once (one numpy
array per state, 13 elements with the defaults): with one call per point in Python floats
an update took 0.27 ms, with one call for all 0.20 ms (:mod:`.ukf`'s cost paragraph).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Final, TypeAlias

import numpy as np
import numpy.typing as npt

from .base import BackendError
from .params_file import check_keys, finite_number, read_params_file

SHIPPED_DIR: Final = "data/ukf"
GRAVITY_MPS2: Final = 9.80665
MIN_VX_MPS: Final = 0.5
"""Slip angles of a state with a smaller v_x [m/s] use this (a sigma point may go there)."""
_MIN_FRICTION: Final = 0.05  # a sigma point's μ is floored here (the tyre model's floor)
Values: TypeAlias = float | npt.NDArray[np.float64]
"""One state's value, or the same quantity of every sigma point (elementwise)."""
AXLES_FROM: Final = ("vehicle", "recordings", "description")
"""Where a file's axle curves come from (its optional ``axles_from`` key): ``vehicle``
(the car's own tyres or full parameters: ``sideslip_sim.ukf_params``; the default),
``recordings`` (identified from the car's drives: ``sideslip-identify-axles``) or
``description`` (the fleet's typical tyres for a car known by its description:
``sideslip-fit``). The filter reads the same curves whatever the source; a model that
reads the filter may publish another σ for a described file, whose tyres are a guess
(:class:`~sideslip_msgs_py.uncertainty.Uncertainty`'s ``described``)."""


@dataclass(frozen=True)
class UkfParams:
    """Nominal vehicle and per-axle Magic Formula (``python -m sideslip_sim.ukf_params``)."""

    name: str
    mass_kg: float
    yaw_inertia_kgm2: float
    cg_to_front_axle_m: float
    cg_to_rear_axle_m: float
    cg_height_m: float
    stl_per_road_wheel_angle_m_per_rad: float
    mf_b_front: float
    mf_c_front: float
    mf_e_front: float
    mu_peak_front: float
    mf_b_rear: float
    mf_c_rear: float
    mf_e_rear: float
    mu_peak_rear: float
    relaxation_length_front_m: float
    relaxation_length_rear_m: float
    axles_from: str = field(default="vehicle", compare=False)
    """:data:`AXLES_FROM`: where the axle curves came from (not read by the filter)."""

    @classmethod
    def load(cls, source: str) -> UkfParams:
        """From a YAML path, or the name of a shipped file (``paper_sedan``, ...)."""
        data, where = read_params_file("ukf", source, SHIPPED_DIR)
        return cls.from_mapping(data, where)

    @classmethod
    def from_mapping(cls, data: object, where: str) -> UkfParams:
        if isinstance(data, dict) and "axles_from" in data:
            data = dict(data)
            axles_from = data.pop("axles_from")
            if axles_from not in AXLES_FROM:
                raise BackendError(
                    f"{where}: axles_from must be one of {AXLES_FROM}, got {axles_from!r}"
                )
        else:
            axles_from = "vehicle"
        names = [f.name for f in fields(cls) if f.name != "axles_from"]
        data = check_keys(data, where, names, "ukf parameters")
        values: dict[str, object] = {"name": str(data["name"]), "axles_from": axles_from}
        for n in names[1:]:
            v = finite_number(where, n, data[n])
            # MF 5.2's ranges: C in (0, 2] (a larger C turns the force back), E ≤ 1 (any
            # sign); everything else is a positive physical quantity.
            if n.startswith("mf_e_"):
                if v > 1.0:
                    raise BackendError(f"{where}: {n} must be <= 1, got {v!r}")
            elif n.startswith("mf_c_"):
                if not 0.0 < v <= 2.0:
                    raise BackendError(f"{where}: {n} must be in (0, 2], got {v!r}")
            elif not v > 0.0:
                raise BackendError(f"{where}: {n} must be a positive finite number, got {v!r}")
            values[n] = v
        return cls(**values)  # type: ignore[arg-type]


class SingleTrackMagicFormula:
    """The model of the module docstring, elementwise over the states (:data:`Values`);
    the inputs δ [rad] and a_x [m/s²] are one value for all of them."""

    def __init__(self, p: UkfParams) -> None:
        self.m, self.iz = p.mass_kg, p.yaw_inertia_kgm2
        self.a, self.b, self.h = p.cg_to_front_axle_m, p.cg_to_rear_axle_m, p.cg_height_m
        length = self.a + self.b
        self.fz_front_n = p.mass_kg * GRAVITY_MPS2 * self.b / length
        self.fz_rear_n = p.mass_kg * GRAVITY_MPS2 * self.a / length
        self.transfer_per_ax = p.mass_kg * self.h / length  # ΔF_z per a_x [N per m/s²]
        self.front = (p.mf_b_front, p.mf_c_front, p.mf_e_front, p.mu_peak_front * self.fz_front_n)
        self.rear = (p.mf_b_rear, p.mf_c_rear, p.mf_e_rear, p.mu_peak_rear * self.fz_rear_n)
        self.relaxation_front_m = p.relaxation_length_front_m
        self.relaxation_rear_m = p.relaxation_length_rear_m

    def slip_angles(
        self, v_x: Values, v_y: Values, r: Values, delta: float
    ) -> tuple[Values, Values]:
        """Kinematic (α_f, α_r) [rad] of the axles."""
        v_x = np.maximum(v_x, MIN_VX_MPS)
        return delta - np.arctan((v_y + self.a * r) / v_x), -np.arctan((v_y - self.b * r) / v_x)

    @staticmethod
    def _axle(mf: tuple[float, float, float, float], alpha: Values, mu: Values) -> Values:
        b, c, e, d = mf
        x = b * alpha / mu
        return mu * d * np.sin(c * np.arctan(x - e * (x - np.arctan(x))))

    def forces(
        self, alpha_f: Values, alpha_r: Values, mu: Values, a_x: float
    ) -> tuple[Values, Values]:
        """(F_yf, F_yr) [N], each axle's lateral force in its own wheel frame."""
        mu = np.maximum(mu, _MIN_FRICTION)
        shift = self.transfer_per_ax * a_x
        # F_z/F_z0 scales the whole axle curve; floored so heavy braking cannot flip it.
        load_f = max(1.0 - shift / self.fz_front_n, 0.0)
        load_r = max(1.0 + shift / self.fz_rear_n, 0.0)
        return (
            load_f * self._axle(self.front, alpha_f, mu),
            load_r * self._axle(self.rear, alpha_r, mu),
        )

    def accelerations(
        self,
        v_x: Values,
        v_y: Values,
        r: Values,
        f_front: Values,
        f_rear: Values,
        delta: float,
        a_x: float,
    ) -> tuple[Values, Values, Values]:
        """(v̇_x, v̇_y, ψ̈) of the module docstring for the axle forces [N]."""
        f_front = f_front * math.cos(delta)
        return (
            a_x + r * v_y,
            (f_front + f_rear) / self.m - r * v_x,
            (self.a * f_front - self.b * f_rear) / self.iz,
        )
