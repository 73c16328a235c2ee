"""A seeded sampler of realistic passenger cars, and the checks that reject implausible ones.

Every car is drawn from the ranges of `FleetRanges` (kg, m, rad, Hz); quantities that
an engineer would not choose independently are derived, not drawn: the yaw inertia from
a dynamic index k = I_z/(m·a·b), spring rates from a ride frequency, dampers from a
damping ratio, anti-roll bars from a roll gradient and a front roll-stiffness share,
the tyres' nominal load from the car's static wheel load (a heavier car gets a bigger
tyre of the same family).

Tyres: one family (the vehicle's tyre file) in four characteristics, each a pair of
Magic Formula scalings (cornering stiffness, peak friction), with a per-axle spread on
top (staggered or mixed tyres). The rear axle's cornering stiffness is then set so that
the car has a drawn understeer gradient (1–4 deg/g): it stands for everything a
manufacturer tunes the balance with (tyre sizes and pressures, compliance steer).

=============  =========  ==========
characteristic  K scale    μ scale
=============  =========  ==========
touring        1.00       1.00
performance    1.30       1.10
all_season     0.85       0.93
eco            0.90       0.95
=============  =========  ==========

Cars that fail the plausibility checks (:mod:`sideslip_sim.plausibility`) are drawn
again.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sideslip_sim.plausibility import DEG_PER_G, plausibility_problems
from sideslip_sim.single_track import SingleTrack
from sideslip_sim.tire import DEFAULT_TIR, TireParams, load_tire
from sideslip_sim.vehicle import (
    GRAVITY_MPS2,
    TIRE_SCALE_RANGE,
    VehicleParams,
    vehicle_from_dict,
)

TIRE_CHARACTERISTICS: dict[str, tuple[float, float]] = {
    "touring": (1.00, 1.00),
    "performance": (1.30, 1.10),
    "all_season": (0.85, 0.93),
    "eco": (0.90, 0.95),
}


class FleetError(ValueError):
    """The sampler could not draw a plausible car (ranges too tight) or bad options."""


@dataclass(frozen=True)
class FleetRanges:
    """Uniform ranges [low, high] of the drawn quantities (units in the names)."""

    mass_kg: tuple[float, float] = (900.0, 2600.0)  # including payload
    wheelbase_m: tuple[float, float] = (2.3, 3.2)
    front_weight_fraction: tuple[float, float] = (0.38, 0.65)
    cg_height_m: tuple[float, float] = (0.45, 0.75)
    dynamic_index: tuple[float, float] = (0.8, 1.2)
    track_m: tuple[float, float] = (1.4, 1.7)
    stl_per_road_wheel_angle_m_per_rad: tuple[float, float] = (1.2, 2.0)
    roll_steer_front_rad_per_rad: tuple[float, float] = (-0.02, 0.12)
    roll_steer_rear_rad_per_rad: tuple[float, float] = (-0.05, 0.08)
    tire_rolling_radius_m: tuple[float, float] = (0.29, 0.36)
    axle_tire_spread: float = 0.08  # per-axle ± fraction on the characteristic's scales
    ride_frequency_front_hz: tuple[float, float] = (1.1, 1.5)
    damping_ratio: tuple[float, float] = (0.25, 0.40)
    roll_gradient_deg_per_g: tuple[float, float] = (3.0, 6.5)
    understeer_gradient_deg_per_g: tuple[float, float] = (1.0, 4.0)
    front_roll_stiffness_share: tuple[float, float] = (0.50, 0.70)
    # The paper's tyre is a 205/60R15 (F_z0 = 4000 N): its nominal load is scaled so that
    # the static wheel load is this fraction of the nominal (passenger-car sizing).
    wheel_load_over_nominal: tuple[float, float] = (0.7, 1.0)
    layout: str | None = None
    """fwd, rwd or awd for every car; None: drawn (45 / 25 / 30 %)."""


def vehicle_digest(vehicle: VehicleParams) -> str:
    """SHA-256 of the physical parameters (name, description and file path excluded):
    two cars with one digest drive identically."""
    params = dataclasses.asdict(vehicle)
    for key in ("name", "description", "source_path"):
        params.pop(key)
    text = json.dumps(params, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _tire_path(tire_file: str) -> Path:
    path = Path(tire_file)
    return path if path.is_absolute() else DEFAULT_TIR.parent / path.name


def _uniform(rng: np.random.Generator, bounds: tuple[float, float]) -> float:
    return float(rng.uniform(*bounds))


@dataclass(frozen=True)
class CarDesign:
    """The primary choices of one car (units in the names); `design_vehicle` derives the
    rest. Fractions are of the whole-vehicle weight; ride frequencies in Hz."""

    layout: str
    mass_kg: float
    wheelbase_m: float
    front_weight_fraction: float
    cg_height_m: float
    track_front_m: float
    track_rear_m: float
    dynamic_index: float
    tire_rolling_radius_m: float
    tire_characteristic: str
    tire_scale_spread_front: tuple[float, float]  # (K, μ) multipliers on the characteristic
    tire_scale_spread_rear: tuple[float, float]
    wheel_load_over_nominal: float
    understeer_gradient_deg_per_g: float
    stl_per_road_wheel_angle_m_per_rad: float
    roll_steer_front_rad_per_rad: float
    roll_steer_rear_rad_per_rad: float
    ride_frequency_front_hz: float
    ride_frequency_rear_over_front: float
    damping_ratio: float
    roll_gradient_deg_per_g: float
    front_roll_stiffness_share: float
    roll_center_height_front_m: float
    roll_center_height_rear_m: float
    unsprung_extra_front_kg: float = 10.0
    unsprung_extra_rear_kg: float = 8.0
    roll_gyration_m: float = 0.58
    pitch_gyration_over_wheelbase: float = 0.42
    wheel_inertia_factor_front: float = 1.0
    wheel_inertia_factor_rear: float = 1.0
    ackermann_fraction: float = 0.6
    max_road_wheel_angle_deg: float = 35.0
    awd_front_fraction: float = 0.4
    drag_coefficient: float = 0.30
    frontal_area_m2: float = 2.2
    description: str = ""


def draw_design(rng: np.random.Generator, ranges: FleetRanges) -> CarDesign:
    """One car's primary choices from the ranges."""
    layout = ranges.layout or str(rng.choice(["fwd", "rwd", "awd"], p=[0.45, 0.25, 0.30]))
    # Front-drive cars carry the engine over the front axle; rear-drive ones are the
    # balanced ones: the layout shifts the front weight fraction within the range.
    lo, hi = ranges.front_weight_fraction
    span = {"fwd": (0.55, 1.0), "rwd": (0.0, 0.6), "awd": (0.2, 0.8)}[layout]
    front_fraction = lo + (hi - lo) * float(rng.uniform(*span))
    wheelbase = _uniform(rng, ranges.wheelbase_m)
    # Mass grows with size; the draw around that trend covers the whole range.
    m_lo, m_hi = ranges.mass_kg
    w_lo, w_hi = ranges.wheelbase_m
    trend = m_lo + (m_hi - m_lo) * (wheelbase - w_lo) / (w_hi - w_lo)
    mass = trend + rng.normal(0.0, 300.0)
    while not m_lo <= mass <= m_hi:  # truncated, not clipped: no pile-up at the bounds
        mass = trend + rng.normal(0.0, 300.0)
    track_front = _uniform(rng, ranges.track_m)
    spread = ranges.axle_tire_spread

    def axle_spread() -> tuple[float, float]:
        return (1.0 + rng.uniform(-spread, spread), 1.0 + rng.uniform(-spread, spread))

    return CarDesign(
        layout=layout,
        mass_kg=float(mass),
        wheelbase_m=wheelbase,
        front_weight_fraction=front_fraction,
        cg_height_m=_uniform(rng, ranges.cg_height_m),
        track_front_m=track_front,
        track_rear_m=float(np.clip(track_front + rng.uniform(-0.05, 0.05), *ranges.track_m)),
        dynamic_index=_uniform(rng, ranges.dynamic_index),
        tire_rolling_radius_m=_uniform(rng, ranges.tire_rolling_radius_m),
        tire_characteristic=str(rng.choice(list(TIRE_CHARACTERISTICS))),
        tire_scale_spread_front=axle_spread(),
        tire_scale_spread_rear=axle_spread(),
        wheel_load_over_nominal=_uniform(rng, ranges.wheel_load_over_nominal),
        understeer_gradient_deg_per_g=_uniform(rng, ranges.understeer_gradient_deg_per_g),
        stl_per_road_wheel_angle_m_per_rad=_uniform(rng, ranges.stl_per_road_wheel_angle_m_per_rad),
        roll_steer_front_rad_per_rad=_uniform(rng, ranges.roll_steer_front_rad_per_rad),
        roll_steer_rear_rad_per_rad=_uniform(rng, ranges.roll_steer_rear_rad_per_rad),
        ride_frequency_front_hz=_uniform(rng, ranges.ride_frequency_front_hz),
        ride_frequency_rear_over_front=float(rng.uniform(1.0, 1.2)),  # flat ride
        damping_ratio=_uniform(rng, ranges.damping_ratio),
        roll_gradient_deg_per_g=_uniform(rng, ranges.roll_gradient_deg_per_g),
        front_roll_stiffness_share=_uniform(rng, ranges.front_roll_stiffness_share),
        roll_center_height_front_m=float(rng.uniform(0.03, 0.12)),
        roll_center_height_rear_m=float(rng.uniform(0.06, 0.15)),
        unsprung_extra_front_kg=float(rng.uniform(5.0, 15.0)),
        unsprung_extra_rear_kg=float(rng.uniform(3.0, 13.0)),
        roll_gyration_m=float(rng.uniform(0.50, 0.65)),
        pitch_gyration_over_wheelbase=float(rng.uniform(0.38, 0.46)),
        wheel_inertia_factor_front=float(rng.uniform(0.8, 1.2)),
        wheel_inertia_factor_rear=float(rng.uniform(0.8, 1.2)),
        ackermann_fraction=float(rng.uniform(0.3, 1.0)),
        max_road_wheel_angle_deg=float(rng.uniform(32.0, 38.0)),
        awd_front_fraction=float(rng.uniform(0.3, 0.6)),
        drag_coefficient=float(rng.uniform(0.25, 0.38)),
        frontal_area_m2=1.9 + 0.6 * (mass - m_lo) / (m_hi - m_lo) + float(rng.uniform(-0.1, 0.1)),
    )


def design_vehicle(design: CarDesign, tire: TireParams, tire_file: str, name: str) -> VehicleParams:
    """The full vehicle of a design (not yet checked for plausibility); tire is the
    parsed tire_file (a shipped name or a path, as a vehicle file gives it)."""
    d = design
    g = GRAVITY_MPS2
    mass, wheelbase = d.mass_kg, d.wheelbase_m
    b = d.front_weight_fraction * wheelbase  # CG to rear axle: the front axle carries b/L
    a = wheelbase - b
    unsprung_front = 0.016 * mass + d.unsprung_extra_front_kg  # per corner, kg
    unsprung_rear = 0.014 * mass + d.unsprung_extra_rear_kg
    sprung = mass - 2.0 * (unsprung_front + unsprung_rear)

    # Springs from the ride frequency of each corner's sprung mass; dampers from ζ.
    corner_f = 0.5 * mass * b / wheelbase - unsprung_front
    corner_r = 0.5 * mass * a / wheelbase - unsprung_rear
    k_front = (2.0 * math.pi * d.ride_frequency_front_hz) ** 2 * corner_f
    k_rear = (2.0 * math.pi * d.ride_frequency_front_hz * d.ride_frequency_rear_over_front) ** 2
    k_rear *= corner_r
    c_front = 2.0 * d.damping_ratio * math.sqrt(k_front * corner_f)
    c_rear = 2.0 * d.damping_ratio * math.sqrt(k_rear * corner_r)
    # Anti-roll bars: total roll stiffness for the roll gradient, shared front/rear; the
    # springs give k·t²/2 per axle, the bars the rest (never negative).
    arm = max(
        d.cg_height_m - 0.5 * (d.roll_center_height_front_m + d.roll_center_height_rear_m), 0.1
    )
    gradient = math.radians(d.roll_gradient_deg_per_g) / g  # rad per m/s²
    total_roll = sprung * arm / gradient + sprung * g * arm
    share = d.front_roll_stiffness_share
    arb_front = max(share * total_roll - 0.5 * k_front * d.track_front_m**2, 0.0)
    arb_rear = max((1.0 - share) * total_roll - 0.5 * k_rear * d.track_rear_m**2, 0.0)

    k_scale, mu_scale = TIRE_CHARACTERISTICS[d.tire_characteristic]
    static_corner = 0.5 * mass * g * max(a, b) / wheelbase
    load_scale = static_corner / (d.wheel_load_over_nominal * tire.fnomin_n * tire["LFZO"])
    radius = d.tire_rolling_radius_m
    description = d.description or (
        f"fleet car: {d.layout.upper()}, {mass:.0f} kg, L {wheelbase:.2f} m, "
        f"{100 * d.front_weight_fraction:.0f}% front, {d.tire_characteristic} tyres"
    )
    values = {
        "name": name,
        "description": description,
        "sprung_mass_kg": sprung,
        "unsprung_mass_front_kg": unsprung_front,
        "unsprung_mass_rear_kg": unsprung_rear,
        "cg_to_front_axle_m": a,
        "cg_to_rear_axle_m": b,
        "cg_height_m": d.cg_height_m,
        "track_front_m": d.track_front_m,
        "track_rear_m": d.track_rear_m,
        "roll_center_height_front_m": d.roll_center_height_front_m,
        "roll_center_height_rear_m": d.roll_center_height_rear_m,
        "roll_inertia_kgm2": sprung * d.roll_gyration_m**2,
        "pitch_inertia_kgm2": sprung * (d.pitch_gyration_over_wheelbase * wheelbase) ** 2,
        "yaw_inertia_kgm2": d.dynamic_index * mass * a * b,
        "spring_front_n_per_m": k_front,
        "spring_rear_n_per_m": k_rear,
        "damper_front_ns_per_m": c_front,
        "damper_rear_ns_per_m": c_rear,
        "antiroll_front_nm_per_rad": arb_front,
        "antiroll_rear_nm_per_rad": arb_rear,
        "wheel_spin_inertia_front_kgm2": d.wheel_inertia_factor_front * 10.0 * radius**2,
        "wheel_spin_inertia_rear_kgm2": d.wheel_inertia_factor_rear * 10.0 * radius**2,
        "tire_rolling_radius_m": radius,
        "tire_file": tire_file,
        "tire_nominal_load_scale": float(np.clip(load_scale, *TIRE_SCALE_RANGE)),
        "tire_cornering_stiffness_scale_front": k_scale * d.tire_scale_spread_front[0],
        "tire_cornering_stiffness_scale_rear": k_scale * d.tire_scale_spread_rear[0],
        "tire_peak_friction_scale_front": mu_scale * d.tire_scale_spread_front[1],
        "tire_peak_friction_scale_rear": mu_scale * d.tire_scale_spread_rear[1],
        "stl_per_road_wheel_angle_m_per_rad": d.stl_per_road_wheel_angle_m_per_rad,
        "ackermann_fraction": d.ackermann_fraction,
        "max_road_wheel_angle_rad": math.radians(d.max_road_wheel_angle_deg),
        "roll_steer_front_rad_per_rad": d.roll_steer_front_rad_per_rad,
        "roll_steer_rear_rad_per_rad": d.roll_steer_rear_rad_per_rad,
        "drive_layout": d.layout,
        "drive_front_fraction": {"fwd": 1.0, "rwd": 0.0, "awd": d.awd_front_fraction}[d.layout],
        "drag_coefficient": d.drag_coefficient,
        "frontal_area_m2": d.frontal_area_m2,
        "air_density_kg_per_m3": 1.225,
    }
    # Rounded so that a car written to YAML and read back has the same digest.
    rounded = {k: round(float(v), 6) if isinstance(v, float) else v for k, v in values.items()}
    car = _vehicle(rounded, name)
    # Balance: manufacturers tune every car to understeer mildly (tyre sizes and
    # pressures, compliance steer); here the rear axle's effective cornering stiffness
    # is set to give the design's understeer gradient K = (m/L)(b/C_f − a/C_r).
    target = d.understeer_gradient_deg_per_g * DEG_PER_G
    model = SingleTrack.from_vehicle(car, tire)
    slack = model.b_m / model.c_front_n_per_rad - target * model.wheelbase_m / model.mass_kg
    if slack <= 0.0:
        return car  # no rear stiffness gives it: the plausibility checks reject the car
    rear_scale = car.tire_cornering_stiffness_scale_rear * (
        model.a_m / slack / model.c_rear_n_per_rad
    )
    # Beyond the scaling range it would be another tyre: clipped, and the plausibility
    # checks judge the result.
    rear_scale = float(np.clip(rear_scale, *TIRE_SCALE_RANGE))
    rounded["tire_cornering_stiffness_scale_rear"] = round(rear_scale, 6)
    return _vehicle(rounded, name)


def centred_ranges(
    *,
    mass_kg: float,
    wheelbase_m: float,
    front_weight_fraction: float,
    cg_height_m: float,
    track_m: float,
    stl_per_road_wheel_angle_m_per_rad: float,
    tire_rolling_radius_m: float,
    layout: str | None = None,
) -> FleetRanges:
    """Ranges around one car's nominal parameters (what an owner can look up: mass ± 5 %,
    wheelbase ± 1 %, weight split ± 0.02, CG height ± 0.05 m, track ± 0.02 m, steering
    ratio ± 3 %, tyre radius ± 0.01 m); everything else (inertia, tyres, suspension,
    understeer) keeps the fleet's spread, as the uncertainty about the car."""
    if layout is not None and layout not in ("fwd", "rwd", "awd"):
        raise FleetError(f"layout must be fwd, rwd or awd, got {layout!r}")

    def around(value: float, half: float) -> tuple[float, float]:
        return (value - half, value + half)

    return FleetRanges(
        mass_kg=around(mass_kg, 0.05 * mass_kg),
        wheelbase_m=around(wheelbase_m, 0.01 * wheelbase_m),
        front_weight_fraction=around(front_weight_fraction, 0.02),
        cg_height_m=around(cg_height_m, 0.05),
        track_m=around(track_m, 0.02),
        stl_per_road_wheel_angle_m_per_rad=around(
            stl_per_road_wheel_angle_m_per_rad, 0.03 * stl_per_road_wheel_angle_m_per_rad
        ),
        tire_rolling_radius_m=around(tire_rolling_radius_m, 0.01),
        layout=layout,
    )


def _vehicle(values: dict[str, object], name: str) -> VehicleParams:
    # Checked like a vehicle file, but it comes from no file: no source path.
    return dataclasses.replace(vehicle_from_dict(values, where=f"car {name}"), source_path="")


@dataclass(frozen=True)
class FleetDraw:
    """Cars drawn by `sample_fleet`, and how many candidates each check rejected."""

    vehicles: list[VehicleParams]
    rejected: dict[str, int]


def sample_fleet(
    count: int,
    seed: int,
    *,
    tire_file: str = DEFAULT_TIR.name,
    prefix: str = "fleet",
    ranges: FleetRanges | None = None,
    exclude_digests: frozenset[str] = frozenset(),
    max_tries_per_car: int = 200,
) -> FleetDraw:
    """`count` plausible cars from a seeded generator (same seed, same cars).

    exclude_digests: parameter digests that must never be drawn (the held-out cars).
    """
    if count < 1:
        raise FleetError(f"fleet: count must be >= 1, got {count}")
    ranges = ranges or FleetRanges()
    tire = load_tire(str(_tire_path(tire_file)))
    rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xF1EE7])
    vehicles: list[VehicleParams] = []
    rejected: dict[str, int] = {}
    for i in range(count):
        for _ in range(max_tries_per_car):
            design = draw_design(rng, ranges)
            car = design_vehicle(design, tire, tire_file, f"{prefix}{seed}_car{i:03d}")
            problems = plausibility_problems(car, tire)
            if vehicle_digest(car) in exclude_digests:
                problems.append("identical to a held-out car")
            if not problems:
                vehicles.append(car)
                break
            for problem in problems:
                key = problem.split(" ")[0] + " " + problem.split(" ")[1]
                rejected[key] = rejected.get(key, 0) + 1
        else:
            raise FleetError(
                f"fleet: no plausible car in {max_tries_per_car} draws (rejections: {rejected})"
            )
    return FleetDraw(vehicles, rejected)
