"""Whether a car is a plausible passenger car: the checks the fleet sampler applies.

Plausibility checks (`plausibility_problems`), on the linear single-track model with
the axle tyres at their static loads:

* understeer gradient K_us between 0.5 and 5 deg/g: every production car understeers
  mildly in the linear range (neutral or oversteering cars are not sold);
* static margin (b·C_r − a·C_f)/(L·(C_f + C_r)) between 0.01 and 0.25 (same reason,
  stated on the tyre forces instead of the gradient);
* static stability factor t/(2h) ≥ 1.05: the car slides before it tips on a level road
  (US NCAP SUVs are 1.05–1.25, cars 1.3–1.5);
* static wheel load at most 2.5× the tyre's (scaled) nominal load.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import TireParams
from sideslip_sim.vehicle import GRAVITY_MPS2, VehicleParams

DEG_PER_G = math.radians(1.0) / GRAVITY_MPS2  # 1 deg/g in rad per (m/s²)


@dataclass(frozen=True)
class Plausibility:
    """The checked figures of one car (units in the names)."""

    understeer_gradient_deg_per_g: float
    static_margin: float
    static_stability_factor: float
    max_wheel_load_over_nominal: float


def plausibility(vehicle: VehicleParams, tire: TireParams) -> Plausibility:
    model = SingleTrack.from_vehicle(vehicle, tire)
    cf, cr = model.c_front_n_per_rad, model.c_rear_n_per_rad
    margin = (model.b_m * cr - model.a_m * cf) / (model.wheelbase_m * (cf + cr))
    track = 0.5 * (vehicle.track_front_m + vehicle.track_rear_m)
    nominal = tire.fnomin_n * tire["LFZO"] * vehicle.tire_nominal_load_scale
    corner = 0.5 * max(vehicle.static_axle_load_front_n, vehicle.static_axle_load_rear_n)
    return Plausibility(
        understeer_gradient_deg_per_g=model.understeer_gradient_rad_per_mps2 / DEG_PER_G,
        static_margin=margin,
        static_stability_factor=track / (2.0 * vehicle.cg_height_m),
        max_wheel_load_over_nominal=corner / nominal,
    )


def plausibility_problems(vehicle: VehicleParams, tire: TireParams) -> list[str]:
    """Why this car is not a plausible passenger car (empty: it is)."""
    p = plausibility(vehicle, tire)
    problems = []
    if not 0.5 <= p.understeer_gradient_deg_per_g <= 5.0:
        problems.append(
            f"understeer gradient {p.understeer_gradient_deg_per_g:.2f} deg/g not in [0.5, 5]"
        )
    if not 0.01 <= p.static_margin <= 0.25:
        problems.append(f"static margin {p.static_margin:.3f} not in [0.01, 0.25]")
    if p.static_stability_factor < 1.05:
        problems.append(f"static stability factor {p.static_stability_factor:.2f} < 1.05")
    if p.max_wheel_load_over_nominal > 2.5:
        problems.append(
            f"static wheel load {p.max_wheel_load_over_nominal:.2f}x the tyre's nominal > 2.5"
        )
    return problems
