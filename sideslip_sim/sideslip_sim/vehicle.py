"""Vehicle parameters: a frozen dataclass loaded from a YAML vehicle file.

Frames and signs follow REP-103 (x forward, y left, z up). Every length is in metres,
every mass in kilograms, every angle in radians; the unit is part of each key so the
YAML reads without this file. Unknown or missing keys are errors, never defaults.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

GRAVITY_MPS2 = 9.80665

DRIVE_LAYOUTS = ("fwd", "rwd", "awd")


class VehicleFileError(ValueError):
    """A vehicle file is unreadable, has an unknown/missing key or an implausible value."""


@dataclass(frozen=True)
class VehicleParams:
    """One vehicle. Positions are measured from the whole-vehicle centre of gravity (CG).

    The sprung body carries roll, pitch and heave about its own CG; the four unsprung
    masses move vertically only; the wheels spin about their axles.
    """

    name: str
    description: str
    # Masses (kg). Unsprung masses are per corner.
    sprung_mass_kg: float
    unsprung_mass_front_kg: float
    unsprung_mass_rear_kg: float
    # Geometry (m).
    cg_to_front_axle_m: float
    cg_to_rear_axle_m: float
    cg_height_m: float
    track_front_m: float
    track_rear_m: float
    roll_center_height_front_m: float
    roll_center_height_rear_m: float
    # Sprung-body inertia about its own CG (kg m^2); yaw inertia is the whole vehicle's.
    roll_inertia_kgm2: float
    pitch_inertia_kgm2: float
    yaw_inertia_kgm2: float
    # Suspension, at the wheel (wheel rates).
    spring_front_n_per_m: float
    spring_rear_n_per_m: float
    damper_front_ns_per_m: float
    damper_rear_ns_per_m: float
    antiroll_front_nm_per_rad: float
    antiroll_rear_nm_per_rad: float
    # Wheels and tyres.
    wheel_spin_inertia_front_kgm2: float
    wheel_spin_inertia_rear_kgm2: float
    tire_rolling_radius_m: float
    tire_file: str
    # Scaling of the tyre file's Magic Formula through its user factors: the nominal load
    # (LFZO: a bigger tyre of the same family for a heavier car), and per axle the
    # cornering stiffness (LKY) and peak friction (LMUY, LMUX): another compound, size
    # or inflation on each axle. All 1.0 = the file as measured.
    tire_nominal_load_scale: float
    tire_cornering_stiffness_scale_front: float
    tire_cornering_stiffness_scale_rear: float
    tire_peak_friction_scale_front: float
    tire_peak_friction_scale_rear: float
    # Steering: STL (steering-bar travel, m) -> mean road-wheel angle (rad) is linear.
    stl_per_road_wheel_angle_m_per_rad: float
    ackermann_fraction: float
    max_road_wheel_angle_rad: float
    # Roll steer: road-wheel angle per body roll angle (rad/rad) of each axle, > 0 roll
    # understeer (the front wheels steer out of the turn, the rear wheels into it).
    roll_steer_front_rad_per_rad: float
    roll_steer_rear_rad_per_rad: float
    # Driveline: wheel torque from the manoeuvre, split by an open differential per axle.
    drive_layout: str
    drive_front_fraction: float
    # Aerodynamics.
    drag_coefficient: float
    frontal_area_m2: float
    air_density_kg_per_m3: float
    source_path: str = ""

    # ---- derived quantities -------------------------------------------------------
    @property
    def wheelbase_m(self) -> float:
        return self.cg_to_front_axle_m + self.cg_to_rear_axle_m

    @property
    def unsprung_mass_kg(self) -> float:
        return 2.0 * (self.unsprung_mass_front_kg + self.unsprung_mass_rear_kg)

    @property
    def mass_kg(self) -> float:
        return self.sprung_mass_kg + self.unsprung_mass_kg

    @property
    def static_axle_load_front_n(self) -> float:
        """Front axle load at rest on level ground (N), from the whole-vehicle CG."""
        return self.mass_kg * GRAVITY_MPS2 * self.cg_to_rear_axle_m / self.wheelbase_m

    @property
    def static_axle_load_rear_n(self) -> float:
        return self.mass_kg * GRAVITY_MPS2 * self.cg_to_front_axle_m / self.wheelbase_m

    @property
    def sprung_cg_x_m(self) -> float:
        """x of the sprung-mass CG relative to the whole-vehicle CG (m)."""
        mu_f, mu_r = self.unsprung_mass_front_kg, self.unsprung_mass_rear_kg
        moment = 2.0 * (mu_f * self.cg_to_front_axle_m - mu_r * self.cg_to_rear_axle_m)
        return -moment / self.sprung_mass_kg

    @property
    def sprung_cg_height_m(self) -> float:
        """Height of the sprung-mass CG (m): the unsprung masses sit at the wheel centres."""
        unsprung_moment = self.unsprung_mass_kg * self.tire_rolling_radius_m
        return (self.mass_kg * self.cg_height_m - unsprung_moment) / self.sprung_mass_kg

    @property
    def front_drive_fraction(self) -> float:
        """Fraction of the manoeuvre's wheel torque that goes to the front axle."""
        return {"fwd": 1.0, "rwd": 0.0, "awd": self.drive_front_fraction}[self.drive_layout]

    def tire_path(self) -> Path:
        """The tyre property file: relative paths resolve beside the vehicle file, then in
        the package's shipped `data/tires/`."""
        candidate = Path(self.tire_file)
        if candidate.is_absolute():
            return candidate
        if self.source_path:
            beside = Path(self.source_path).parent / candidate
            if beside.exists():
                return beside
            beside_tires = Path(self.source_path).parent.parent / "tires" / candidate
            if beside_tires.exists():
                return beside_tires
        shipped = resources.files("sideslip_sim") / "data" / "tires" / candidate.name
        return Path(str(shipped))


_FIELDS = {f.name: f for f in dataclasses.fields(VehicleParams) if f.name != "source_path"}
_POSITIVE = {
    name
    for name, f in _FIELDS.items()
    if f.type == "float"
    and name
    not in {
        "ackermann_fraction",
        "drive_front_fraction",
        "antiroll_front_nm_per_rad",
        "antiroll_rear_nm_per_rad",
        "roll_center_height_front_m",
        "roll_center_height_rear_m",
        "roll_steer_front_rad_per_rad",
        "roll_steer_rear_rad_per_rad",
    }
}
# Tyre scaling beyond these factors is another tyre, not a scaled one.
TIRE_SCALE_RANGE = (0.5, 2.0)
# Roll steer of production suspensions stays within about ±0.25 rad/rad.
MAX_ABS_ROLL_STEER = 0.3


def _validate(values: dict[str, Any], where: str) -> None:
    for name in _POSITIVE:
        if not values[name] > 0.0:
            raise VehicleFileError(f"{where}: {name} must be > 0, got {values[name]!r}")
    for name in ("antiroll_front_nm_per_rad", "antiroll_rear_nm_per_rad"):
        if values[name] < 0.0:
            raise VehicleFileError(f"{where}: {name} must be >= 0, got {values[name]!r}")
    for name in ("ackermann_fraction", "drive_front_fraction"):
        if not 0.0 <= values[name] <= 1.0:
            raise VehicleFileError(f"{where}: {name} must be in [0, 1], got {values[name]!r}")
    if values["drive_layout"] not in DRIVE_LAYOUTS:
        raise VehicleFileError(
            f"{where}: drive_layout must be one of {DRIVE_LAYOUTS}, got {values['drive_layout']!r}"
        )
    if values["max_road_wheel_angle_rad"] >= math.radians(60.0):
        raise VehicleFileError(f"{where}: max_road_wheel_angle_rad must be < 60 deg in radians")
    for name in (
        "tire_nominal_load_scale",
        "tire_cornering_stiffness_scale_front",
        "tire_cornering_stiffness_scale_rear",
        "tire_peak_friction_scale_front",
        "tire_peak_friction_scale_rear",
    ):
        low, high = TIRE_SCALE_RANGE
        if not low <= values[name] <= high:
            raise VehicleFileError(
                f"{where}: {name} must be in [{low}, {high}], got {values[name]!r}"
            )
    for name in ("roll_steer_front_rad_per_rad", "roll_steer_rear_rad_per_rad"):
        if abs(values[name]) > MAX_ABS_ROLL_STEER:
            raise VehicleFileError(
                f"{where}: {name} must be within ±{MAX_ABS_ROLL_STEER}, got {values[name]!r}"
            )
    for name in ("roll_center_height_front_m", "roll_center_height_rear_m"):
        if not 0.0 <= values[name] < values["cg_height_m"]:
            raise VehicleFileError(f"{where}: {name} must be in [0, cg_height_m)")


def vehicle_from_dict(data: dict[str, Any], where: str = "<dict>") -> VehicleParams:
    """Build parameters from a mapping; `where` names the source in error messages."""
    if not isinstance(data, dict):
        raise VehicleFileError(f"{where}: expected a mapping of keys to values")
    unknown = sorted(set(data) - set(_FIELDS))
    if unknown:
        raise VehicleFileError(f"{where}: unknown key(s) {', '.join(unknown)}")
    missing = sorted(set(_FIELDS) - set(data))
    if missing:
        raise VehicleFileError(f"{where}: missing key(s) {', '.join(missing)}")
    values: dict[str, Any] = {}
    for name, f in _FIELDS.items():
        raw = data[name]
        if f.type == "float":
            if isinstance(raw, bool) or not isinstance(raw, int | float):
                raise VehicleFileError(f"{where}: {name} must be a number, got {raw!r}")
            if not math.isfinite(float(raw)):
                raise VehicleFileError(f"{where}: {name} must be finite, got {raw!r}")
            values[name] = float(raw)
        else:
            if not isinstance(raw, str):
                raise VehicleFileError(f"{where}: {name} must be a string, got {raw!r}")
            values[name] = raw
    _validate(values, where)
    return VehicleParams(**values, source_path=where if where != "<dict>" else "")


def vehicle_record(vehicle: VehicleParams) -> dict[str, object]:
    """The vehicle's parameters as a bag's metadata records them: every field but the
    file it was read from (:func:`vehicle_from_dict` reads it back)."""
    return {k: v for k, v in dataclasses.asdict(vehicle).items() if k != "source_path"}


def load_vehicle(name_or_path: str | Path) -> VehicleParams:
    """Load a vehicle by shipped name (`paper_sedan`) or by path to a YAML file."""
    path = Path(name_or_path)
    if not path.suffix:
        shipped = resources.files("sideslip_sim") / "data" / "vehicles" / f"{path.name}.yaml"
        if not shipped.is_file():
            raise VehicleFileError(
                f"no shipped vehicle named {str(name_or_path)!r}; "
                f"shipped: {', '.join(shipped_vehicles())}"
            )
        path = Path(str(shipped))
    if not path.is_file():
        raise VehicleFileError(f"vehicle file {path} does not exist")
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        raise VehicleFileError(f"vehicle file {path}: not valid YAML ({exc})") from exc
    return vehicle_from_dict(data, where=str(path))


def shipped_vehicles() -> list[str]:
    folder = resources.files("sideslip_sim") / "data" / "vehicles"
    return sorted(
        p.name.removesuffix(".yaml") for p in folder.iterdir() if p.name.endswith(".yaml")
    )
