"""The held-out fleet: six named cars that no training or selection set may contain.

They span what the fleet sampler draws from, at its corners: a light front-heavy
hatchback, a balanced RWD sedan, a tall AWD SUV, a RWD sports car on stiff wide tyres,
a loaded FWD van and a low AWD EV with a 50/50 split. Each is a `CarDesign` (the
primary choices) turned into full parameters by the same derivations as the fleet, so
that its vehicle file is reproducible and its digest (`vehicle_digest`) is stable.

Every training preset refuses them: `sideslip-generate` will not put a held-out car
into the `fleet` preset or drive one through a training preset, and the fleet sampler
excludes their digests. The held-out benchmark drives each at μ = 1.0, 0.7 and 0.4
through the Table 4 scenarios, a step steer and a sine sweep, with paper noise.
"""

from __future__ import annotations

import functools

from sideslip_sim.fleet import CarDesign, design_vehicle, vehicle_digest
from sideslip_sim.tire import DEFAULT_TIR, load_tire
from sideslip_sim.vehicle import VehicleParams

HELD_OUT_MU = (1.0, 0.7, 0.4)

_COMMON = {
    "dynamic_index": 1.0,
    "wheel_load_over_nominal": 0.85,
    "ride_frequency_rear_over_front": 1.1,
    "damping_ratio": 0.32,
    "roll_center_height_front_m": 0.07,
    "roll_center_height_rear_m": 0.11,
    "tire_scale_spread_front": (1.0, 1.0),
    "tire_scale_spread_rear": (1.0, 1.0),
}

DESIGNS: dict[str, CarDesign] = {
    "heldout_hatchback_fwd": CarDesign(
        **_COMMON | {"dynamic_index": 0.92, "wheel_load_over_nominal": 0.9},
        layout="fwd",
        mass_kg=1050.0,
        wheelbase_m=2.45,
        front_weight_fraction=0.62,
        cg_height_m=0.53,
        track_front_m=1.45,
        track_rear_m=1.43,
        tire_rolling_radius_m=0.29,
        tire_characteristic="eco",
        understeer_gradient_deg_per_g=2.6,
        stl_per_road_wheel_angle_m_per_rad=1.45,
        roll_steer_front_rad_per_rad=0.06,
        roll_steer_rear_rad_per_rad=0.02,
        ride_frequency_front_hz=1.3,
        roll_gradient_deg_per_g=5.5,
        front_roll_stiffness_share=0.62,
        ackermann_fraction=0.5,
        max_road_wheel_angle_deg=36.0,
        drag_coefficient=0.31,
        frontal_area_m2=2.05,
        description="Held out: small FWD hatchback, 1050 kg, 62/38, eco tyres.",
    ),
    "heldout_sedan_rwd": CarDesign(
        **_COMMON,
        layout="rwd",
        mass_kg=1550.0,
        wheelbase_m=2.85,
        front_weight_fraction=0.52,
        cg_height_m=0.54,
        track_front_m=1.56,
        track_rear_m=1.58,
        tire_rolling_radius_m=0.32,
        tire_characteristic="touring",
        understeer_gradient_deg_per_g=1.8,
        stl_per_road_wheel_angle_m_per_rad=1.7,
        roll_steer_front_rad_per_rad=0.04,
        roll_steer_rear_rad_per_rad=0.0,
        ride_frequency_front_hz=1.25,
        roll_gradient_deg_per_g=4.5,
        front_roll_stiffness_share=0.58,
        ackermann_fraction=0.7,
        max_road_wheel_angle_deg=35.0,
        drag_coefficient=0.28,
        frontal_area_m2=2.2,
        description="Held out: RWD mid-size sedan, 1550 kg, 52/48, touring tyres.",
    ),
    "heldout_suv_awd": CarDesign(
        **_COMMON | {"dynamic_index": 1.08, "roll_center_height_front_m": 0.1},
        layout="awd",
        mass_kg=2150.0,
        wheelbase_m=2.90,
        front_weight_fraction=0.55,
        cg_height_m=0.72,
        track_front_m=1.63,
        track_rear_m=1.63,
        tire_rolling_radius_m=0.36,
        tire_characteristic="all_season",
        understeer_gradient_deg_per_g=3.3,
        stl_per_road_wheel_angle_m_per_rad=1.9,
        roll_steer_front_rad_per_rad=0.08,
        roll_steer_rear_rad_per_rad=0.03,
        ride_frequency_front_hz=1.2,
        roll_gradient_deg_per_g=6.0,
        front_roll_stiffness_share=0.64,
        ackermann_fraction=0.6,
        max_road_wheel_angle_deg=34.0,
        awd_front_fraction=0.4,
        drag_coefficient=0.36,
        frontal_area_m2=2.7,
        description="Held out: AWD SUV, 2150 kg, 55/45, high CG (0.72 m), all-season tyres.",
    ),
    "heldout_sports_rwd": CarDesign(
        **_COMMON | {"dynamic_index": 0.88, "tire_scale_spread_rear": (1.05, 1.03)},
        layout="rwd",
        mass_kg=1400.0,
        wheelbase_m=2.45,
        front_weight_fraction=0.47,
        cg_height_m=0.46,
        track_front_m=1.60,
        track_rear_m=1.58,
        tire_rolling_radius_m=0.33,
        tire_characteristic="performance",
        understeer_gradient_deg_per_g=1.1,
        stl_per_road_wheel_angle_m_per_rad=1.3,
        roll_steer_front_rad_per_rad=0.02,
        roll_steer_rear_rad_per_rad=-0.01,
        ride_frequency_front_hz=1.5,
        roll_gradient_deg_per_g=3.2,
        front_roll_stiffness_share=0.55,
        ackermann_fraction=0.4,
        max_road_wheel_angle_deg=33.0,
        drag_coefficient=0.31,
        frontal_area_m2=1.95,
        description="Held out: RWD sports car, 1400 kg, 47/53, stiff wide performance tyres.",
    ),
    "heldout_van_fwd": CarDesign(
        **_COMMON | {"dynamic_index": 1.15, "wheel_load_over_nominal": 0.95},
        layout="fwd",
        mass_kg=2500.0,
        wheelbase_m=3.15,
        front_weight_fraction=0.50,
        cg_height_m=0.74,
        track_front_m=1.68,
        track_rear_m=1.66,
        tire_rolling_radius_m=0.34,
        tire_characteristic="touring",
        understeer_gradient_deg_per_g=3.6,
        stl_per_road_wheel_angle_m_per_rad=2.0,
        roll_steer_front_rad_per_rad=0.10,
        roll_steer_rear_rad_per_rad=0.05,
        ride_frequency_front_hz=1.35,
        roll_gradient_deg_per_g=6.3,
        front_roll_stiffness_share=0.66,
        ackermann_fraction=0.8,
        max_road_wheel_angle_deg=37.0,
        drag_coefficient=0.35,
        frontal_area_m2=2.9,
        description="Held out: loaded FWD van, 2500 kg with payload, 50/50, high CG.",
    ),
    "heldout_ev_awd": CarDesign(
        **_COMMON | {"roll_center_height_front_m": 0.05, "roll_center_height_rear_m": 0.09},
        layout="awd",
        mass_kg=2100.0,
        wheelbase_m=2.90,
        front_weight_fraction=0.50,
        cg_height_m=0.48,
        track_front_m=1.64,
        track_rear_m=1.65,
        tire_rolling_radius_m=0.35,
        tire_characteristic="touring",
        understeer_gradient_deg_per_g=1.6,
        stl_per_road_wheel_angle_m_per_rad=1.6,
        roll_steer_front_rad_per_rad=0.04,
        roll_steer_rear_rad_per_rad=0.0,
        ride_frequency_front_hz=1.3,
        roll_gradient_deg_per_g=3.8,
        front_roll_stiffness_share=0.56,
        ackermann_fraction=0.6,
        max_road_wheel_angle_deg=35.0,
        awd_front_fraction=0.5,
        drag_coefficient=0.24,
        frontal_area_m2=2.35,
        description="Held out: AWD EV, 2100 kg, 50/50, low CG (battery floor), touring tyres.",
    ),
}
HELD_OUT_NAMES = tuple(DESIGNS)


@functools.cache
def held_out_vehicles() -> dict[str, VehicleParams]:
    """The six held-out cars, by name."""
    tire = load_tire(str(DEFAULT_TIR))
    return {
        name: design_vehicle(design, tire, DEFAULT_TIR.name, name)
        for name, design in DESIGNS.items()
    }


@functools.cache
def held_out_digests() -> frozenset[str]:
    """Parameter digests of the held-out cars (what the training presets refuse)."""
    return frozenset(vehicle_digest(v) for v in held_out_vehicles().values())


def is_held_out(vehicle: VehicleParams) -> bool:
    return vehicle_digest(vehicle) in held_out_digests()
