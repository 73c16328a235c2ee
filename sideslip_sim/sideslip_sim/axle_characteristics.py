"""Effective axle characteristics: each axle's lateral force against its single-track
slip angle, as the whole car produces them in steady cornering.

A single-track model lumps an axle's two tyres into one force curve F_y(α). The pure
curve of two equally loaded tyres (:func:`sideslip_sim.ukf_params.fit_axle`) leaves out
what the full car adds as it corners:

- lateral load transfer: the outer tyre gains load, the inner loses it, and with the
  tyre's load sensitivity the pair gives less force than two tyres at the mean load;
  the more so the higher the CG and the stiffer that axle's share of roll stiffness;
- roll steer: body roll turns the wheels, so the slip angle the single-track model
  computes from the rack (front) or from nothing (rear) is not the tyres' own.

The vehicle-dynamics way to keep a single-track model honest is to use *effective*
axle characteristics (Pacejka, *Tyre and Vehicle Dynamics*, ch. 1: the handling diagram
built from axle characteristics that include load transfer and roll steer): measure
each axle's force against the slip angle of the single-track model in quasi-steady
cornering, and fit the curve to that. Here the "measurement" is the full 14-DOF model
(:mod:`sideslip_sim.dynamics`) itself: step steers at 80 km/h on μ = 1 towards 0.1 …
1.0 of μg of steady-state lateral acceleration; from the settled part of each,

    α_f = δ − atan((v + a r)/u),   α_r = −atan((v − b r)/u),   δ = STL / ratio,
    F_yr = (m a_y a − I_z ṙ)/L,      F_yf cos δ = (m a_y b + I_z ṙ)/L,

exactly the quantities the estimator's single-track UKF uses. The Magic Formula's shape
factors C and E stay those of the tyre fit (the settled points reach only part of each
axle's curve, and the rear axle of an understeering car never nears its peak, so four
free parameters would be ill-posed); B and μ_peak are fitted to the points, which moves
the cornering stiffness (roll steer, load transfer at small slip) and the peak (load
transfer near the limit).

Chosen on the validation fleet (docs/training.md, "The UKF's axles"): the UKF's pooled
MAE there fell from 0.141° to 0.104° (steady cornering and step steers to 0.3-0.5× of
before, transients 0.9-0.96×); on ``paper_sedan``, the car the UKF's noise was tuned on,
it rose (paper-test 0.019° → 0.028°). The tests check that the fitted curves pass
through the points and move the way the physics says (a higher CG lowers the peaks,
rear roll understeer stiffens the rear axle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sideslip_sim.maneuvers import LEAD_IN_S, STEP_RAMP_S, Maneuver
from sideslip_sim.simulate import SimulationError, simulate
from sideslip_sim.vehicle import VehicleParams

SPEED_KMH = 80.0
"""Speed of the step steers [km/h]: the held-out benchmark's and a typical road speed."""
AY_FRACTIONS = tuple(round(0.1 * k, 1) for k in range(1, 11))
"""Steady-state lateral accelerations aimed at, as fractions of μg (μ = 1)."""
DURATION_S = 5.0
SETTLE_S = 2.0
"""Samples from this long after the steering ramp ends are used [s] (yaw transients
of passenger cars settle within ~1 s at 80 km/h)."""
MAX_BETA_RAD = math.radians(12.0)
"""A step steer whose |β| exceeds this spun or is spinning: its points are left out."""
MIN_POINTS_PER_AXLE = 200


class CharacteristicError(ValueError):
    """The full model gave too few usable steady-cornering points for a fit."""


@dataclass(frozen=True)
class AxlePoints:
    """Quasi-steady points of both axles: slip angles [rad], forces over static load [-]."""

    alpha_front_rad: np.ndarray
    force_front: np.ndarray
    alpha_rear_rad: np.ndarray
    force_rear: np.ndarray


def steady_cornering_points(
    vehicle: VehicleParams,
    *,
    speed_kmh: float = SPEED_KMH,
    ay_fractions: tuple[float, ...] = AY_FRACTIONS,
) -> AxlePoints:
    """The settled samples of step steers of ``vehicle`` (see module), as axle points.

    Forces are divided by the static axle load m g b/L (front) and m g a/L (rear), the
    normalisation of the UKF's axle curves."""
    a, b = vehicle.cg_to_front_axle_m, vehicle.cg_to_rear_axle_m
    length = a + b
    m, iz = vehicle.mass_kg, vehicle.yaw_inertia_kgm2
    ratio = vehicle.stl_per_road_wheel_angle_m_per_rad
    parts: list[list[np.ndarray]] = [[], [], [], []]
    for fraction in ay_fractions:
        maneuver = Maneuver(
            name=f"{vehicle.name}_axle_characteristic_{fraction:.1f}",
            family="step_steer",
            duration_s=DURATION_S,
            speed_kmh=speed_kmh,
            torque_nm=0.0,
            mu=1.0,
            ay_fraction=fraction,
        )
        try:
            run = simulate(vehicle, maneuver)
        except SimulationError:
            continue  # a run the model cannot integrate gives no steady state
        if np.max(np.abs(run.beta_rad)) > MAX_BETA_RAD:
            continue
        settled = run.t_s > LEAD_IN_S + STEP_RAMP_S + SETTLE_S
        u, v, r = run.u_mps[settled], run.v_mps[settled], run.yaw_rate_radps[settled]
        a_y = run.ay_mps2[settled]
        r_dot = np.gradient(run.yaw_rate_radps, run.t_s)[settled]
        delta = run.stl_m[settled] / ratio
        parts[0].append(delta - np.arctan((v + a * r) / u))
        parts[1].append((m * a_y * b + iz * r_dot) / length / np.cos(delta))
        parts[2].append(-np.arctan((v - b * r) / u))
        parts[3].append((m * a_y * a - iz * r_dot) / length)
    if not parts[0] or sum(p.size for p in parts[0]) < MIN_POINTS_PER_AXLE:
        raise CharacteristicError(
            f"{vehicle.name}: no steady cornering at {speed_kmh:g} km/h to fit axle "
            "characteristics to (every step steer spun or failed)"
        )
    af, ff, ar, fr = (np.concatenate(p) for p in parts)
    fz_front = vehicle.static_axle_load_front_n
    fz_rear = vehicle.static_axle_load_rear_n
    return AxlePoints(af, ff / fz_front, ar, fr / fz_rear)
