"""The car a short description stands for: its known values, the fleet's typical rest.

An owner knows a handful of numbers (mass, wheelbase, CG position and height, track,
steering ratio, tyre radius; :class:`~sideslip_msgs_py.vehicle_description.
VehicleDescription`), not the yaw inertia, the tyres' cornering stiffness or the
suspension. The physics filters need all of it, so this module completes a description
with the *middle* of the fleet's range of each unknown (:class:`~sideslip_sim.fleet.
FleetRanges`): dynamic index 1.0, touring tyres with no per-axle spread, an understeer
gradient of 2.5 deg/g (which sets the rear cornering stiffness), a mid-range tyre load,
roll gradient, ride and roll steer. The result is a full, plausible vehicle; its ``ukf``
params file (``python -m sideslip_sim.ukf_params --description FILE``) is what a user
without the car's tyre data gives the estimator, and what ``sideslip-fit`` trains a
``measurable`` model with, so that training sees the same filter the node will run.

It is a nominal guess, not the car: a real car's tyres and balance differ by as much as
the fleet spreads them, which is the error a model fitted around the description learns
to correct.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_sim.fleet import CarDesign, FleetError, FleetRanges, design_vehicle
from sideslip_sim.plausibility import plausibility_problems
from sideslip_sim.tire import DEFAULT_TIR, load_tire
from sideslip_sim.vehicle import VehicleParams

# Front-drive cars carry the engine over the front axle (the fleet's layouts shift the
# weight split the same way): the layout a description without one most likely has.
_FWD_FROM_FRONT_FRACTION = 0.55


def _middle(bounds: tuple[float, float]) -> float:
    return 0.5 * (bounds[0] + bounds[1])


def described_vehicle(
    *,
    name: str,
    mass_kg: float,
    wheelbase_m: float,
    cg_to_front_axle_m: float,
    cg_height_m: float,
    track_m: float,
    stl_per_road_wheel_angle_m_per_rad: float,
    tire_rolling_radius_m: float,
    layout: str | None = None,
) -> VehicleParams:
    """The full vehicle of a description (units in the names; see the module).

    layout: fwd, rwd or awd; None: fwd when the front axle carries at least 55 % of the
    weight, else rwd. Raises FleetError when the completed car fails the fleet's
    plausibility checks (a description no passenger car matches).
    """
    if not 0.0 < cg_to_front_axle_m < wheelbase_m:
        raise FleetError(
            f"{name}: cg_to_front_axle_m ({cg_to_front_axle_m}) must lie between the axles "
            f"(0, {wheelbase_m})"
        )
    front_fraction = (wheelbase_m - cg_to_front_axle_m) / wheelbase_m
    if layout is None:
        layout = "fwd" if front_fraction >= _FWD_FROM_FRONT_FRACTION else "rwd"
    if layout not in ("fwd", "rwd", "awd"):
        raise FleetError(f"{name}: layout must be fwd, rwd or awd, got {layout!r}")
    r = FleetRanges()
    design = CarDesign(
        layout=layout,
        mass_kg=mass_kg,
        wheelbase_m=wheelbase_m,
        front_weight_fraction=front_fraction,
        cg_height_m=cg_height_m,
        track_front_m=track_m,
        track_rear_m=track_m,
        dynamic_index=_middle(r.dynamic_index),
        tire_rolling_radius_m=tire_rolling_radius_m,
        tire_characteristic="touring",
        tire_scale_spread_front=(1.0, 1.0),
        tire_scale_spread_rear=(1.0, 1.0),
        wheel_load_over_nominal=_middle(r.wheel_load_over_nominal),
        understeer_gradient_deg_per_g=_middle(r.understeer_gradient_deg_per_g),
        stl_per_road_wheel_angle_m_per_rad=stl_per_road_wheel_angle_m_per_rad,
        roll_steer_front_rad_per_rad=_middle(r.roll_steer_front_rad_per_rad),
        roll_steer_rear_rad_per_rad=_middle(r.roll_steer_rear_rad_per_rad),
        ride_frequency_front_hz=_middle(r.ride_frequency_front_hz),
        ride_frequency_rear_over_front=1.1,
        damping_ratio=_middle(r.damping_ratio),
        roll_gradient_deg_per_g=_middle(r.roll_gradient_deg_per_g),
        front_roll_stiffness_share=_middle(r.front_roll_stiffness_share),
        roll_center_height_front_m=0.075,
        roll_center_height_rear_m=0.105,
        description=f"described car {name}: the fleet's typical values for what is unknown",
    )
    tire = load_tire(str(DEFAULT_TIR))
    car = design_vehicle(design, tire, DEFAULT_TIR.name, name)
    problems = plausibility_problems(car, tire)
    if problems:
        raise FleetError(f"{name}: the described car is not plausible: {'; '.join(problems)}")
    return car


def described_from_mapping(
    data: Mapping[str, Any], where: str, name: str | None = None
) -> VehicleParams:
    """The full car of a description mapping (a description file's contents, or a bag's
    vehicle record: only its description keys and ``drive_layout`` are read).

    Raises VehicleDescriptionError for a mapping that is no description, FleetError for
    a car no passenger car matches (both ValueErrors)."""
    nominal = VehicleDescription.from_mapping(data, where=where)
    return described_vehicle(
        name=name or str(data.get("name", where)),
        layout=data.get("drive_layout"),
        **nominal.to_dict(),
    )
