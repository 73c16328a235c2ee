"""A vehicle's nominal parameters: what an owner can look up, and what a model may be
conditioned on (its ``vehicle.*`` inputs, see :mod:`.model_inputs`).

Units in the names (kg, m, m per rad). Read from a short YAML file (``load``) or from a
simulated bag's run metadata, whose ``vehicle`` entry holds the simulator's full
parameter set (``from_mapping`` accepts both: the simulator's keys are a superset).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import yaml

from .errors import ContractError


class VehicleDescriptionError(ContractError, ValueError):
    """A vehicle description is missing a key or has an implausible value."""


@dataclass(frozen=True)
class VehicleDescription:
    """Nominal parameters of a car (whole vehicle incl. payload; REP-103 frame)."""

    mass_kg: float
    wheelbase_m: float
    cg_to_front_axle_m: float
    cg_height_m: float
    track_m: float
    stl_per_road_wheel_angle_m_per_rad: float
    tire_rolling_radius_m: float

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise VehicleDescriptionError(f"vehicle: {f.name} must be a number, got {v!r}")
            if v <= 0.0:
                raise VehicleDescriptionError(f"vehicle: {f.name} must be > 0, got {v!r}")
            object.__setattr__(self, f.name, float(v))
        if not 0.0 < self.cg_to_front_axle_m < self.wheelbase_m:
            raise VehicleDescriptionError(
                "vehicle: cg_to_front_axle_m must lie between the axles "
                f"(0, wheelbase_m = {self.wheelbase_m}), got {self.cg_to_front_axle_m}"
            )

    @property
    def cg_to_rear_axle_m(self) -> float:
        return self.wheelbase_m - self.cg_to_front_axle_m

    @property
    def front_weight_fraction(self) -> float:
        """Share of the static weight on the front axle, b/L [-]."""
        return self.cg_to_rear_axle_m / self.wheelbase_m

    def value(self, name: str) -> float:
        """A field or derived property by name (``front_weight_fraction`` included)."""
        if name == "front_weight_fraction":
            return self.front_weight_fraction
        if name == "cg_to_rear_axle_m":
            return self.cg_to_rear_axle_m
        if name not in {f.name for f in fields(self)}:
            raise VehicleDescriptionError(f"vehicle: no parameter {name!r}")
        return float(getattr(self, name))

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], where: str = "vehicle") -> VehicleDescription:
        """From a description mapping, or from the simulator's full vehicle parameters
        (a bag's ``run_metadata["vehicle"]``: masses, a, b, tracks per axle, ...)."""
        if not isinstance(data, Mapping):
            raise VehicleDescriptionError(f"{where}: expected a mapping of parameters")
        if "sprung_mass_kg" in data:  # the simulator's parameter set
            try:
                a, b = float(data["cg_to_front_axle_m"]), float(data["cg_to_rear_axle_m"])
                mass = float(data["sprung_mass_kg"]) + 2.0 * (
                    float(data["unsprung_mass_front_kg"]) + float(data["unsprung_mass_rear_kg"])
                )
                return cls(
                    mass_kg=mass,
                    wheelbase_m=a + b,
                    cg_to_front_axle_m=a,
                    cg_height_m=float(data["cg_height_m"]),
                    track_m=0.5 * (float(data["track_front_m"]) + float(data["track_rear_m"])),
                    stl_per_road_wheel_angle_m_per_rad=float(
                        data["stl_per_road_wheel_angle_m_per_rad"]
                    ),
                    tire_rolling_radius_m=float(data["tire_rolling_radius_m"]),
                )
            except (KeyError, TypeError, ValueError) as err:
                raise VehicleDescriptionError(
                    f"{where}: bad simulator parameters ({err})"
                ) from None
        names = [f.name for f in fields(cls)]
        # The drive layout is part of a description (sideslip-fit and the described car
        # read it) but no model input: accepted, so that one file serves every tool.
        unknown = sorted(set(data) - set(names) - {"name", "description", "drive_layout"})
        missing = [n for n in names if n not in data]
        if unknown or missing:
            raise VehicleDescriptionError(
                f"{where}: unknown key(s) {unknown}, missing key(s) {missing} "
                f"(a description has: {', '.join(names)})"
            )
        try:
            return cls(**{n: data[n] for n in names})
        except VehicleDescriptionError as err:
            raise VehicleDescriptionError(f"{where}: {err}") from None

    @classmethod
    def load(cls, path: str | Path) -> VehicleDescription:
        """From a YAML file: a description, or a simulator vehicle file."""
        path = Path(path)
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
        except OSError as err:
            raise VehicleDescriptionError(f"{path}: cannot read ({err.strerror})") from None
        except yaml.YAMLError as err:
            raise VehicleDescriptionError(f"{path}: not valid YAML ({err})") from None
        return cls.from_mapping(data, where=str(path))
