"""Per-axle tyres: the vehicle's tyre file with each axle's Magic Formula scaling.

A car's front and rear tyres often differ (staggered sizes, another compound, other
inflation pressures). The vehicle file names one tyre property file and scales it per
axle through the MF 5.2 user scaling factors, which is what those factors are for:

* nominal load ×s_F → LFZO, both axles (a bigger tyre of the same family: F_z0' grows,
  so a heavy car's tyres work at the same relative load as a light car's);
* cornering stiffness ×s_K → LKY (K_y = PKY1·F_z0·sin(2·atan(F_z/(PKY2·F_z0)))·LKY);
* peak friction ×s_μ → LMUY and LMUX (the peak of the lateral and longitudinal curves;
  B = K/(C·D) compensates, so the slip stiffness at zero slip is unchanged).

Both axles of a vehicle with all factors at 1 share the file's coefficients unchanged.
"""

from __future__ import annotations

from sideslip_sim.tire import TireParams
from sideslip_sim.vehicle import VehicleParams


def scaled_tire(
    tire: TireParams, load_scale: float, cornering_scale: float, friction_scale: float
) -> TireParams:
    """The tyre with nominal load, cornering stiffness and peak friction scaled."""
    if load_scale == 1.0 and cornering_scale == 1.0 and friction_scale == 1.0:
        return tire
    return tire.with_values(
        LFZO=tire["LFZO"] * load_scale,
        LKY=tire["LKY"] * cornering_scale,
        LMUY=tire["LMUY"] * friction_scale,
        LMUX=tire["LMUX"] * friction_scale,
    )


def axle_tires(vehicle: VehicleParams, tire: TireParams) -> tuple[TireParams, TireParams]:
    """(front, rear) tyres of the vehicle: its tyre file scaled by each axle's factors."""
    return (
        scaled_tire(
            tire,
            vehicle.tire_nominal_load_scale,
            vehicle.tire_cornering_stiffness_scale_front,
            vehicle.tire_peak_friction_scale_front,
        ),
        scaled_tire(
            tire,
            vehicle.tire_nominal_load_scale,
            vehicle.tire_cornering_stiffness_scale_rear,
            vehicle.tire_peak_friction_scale_rear,
        ),
    )
