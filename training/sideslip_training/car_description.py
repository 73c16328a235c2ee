"""A car as its owner describes it: the short description ``sideslip-fit`` and
``sideslip-identify-axles`` read (``--vehicle``), and what follows from it: the fleet
ranges around it, the full car it stands for and that car's ``ukf`` params file."""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from sideslip_msgs_py.vehicle_description import VehicleDescription, VehicleDescriptionError

from .cli_errors import CliError


@dataclass(frozen=True)
class Description:
    """A car as its owner describes it."""

    name: str
    nominal: VehicleDescription
    layout: str | None

    @classmethod
    def load(cls, path: Path) -> Description:
        try:
            data = yaml.safe_load(path.read_text(encoding="utf-8"))
        except (OSError, yaml.YAMLError) as err:
            raise CliError(f"--vehicle {path}: cannot read ({err})") from None
        if not isinstance(data, dict):
            raise CliError(f"--vehicle {path}: expected a mapping of parameters")
        layout = data.pop("drive_layout", None)
        if layout is not None and layout not in ("fwd", "rwd", "awd"):
            raise CliError(f"--vehicle {path}: drive_layout must be fwd, rwd or awd")
        name = str(data.get("name", path.stem))
        try:
            nominal = VehicleDescription.from_mapping(data, where=str(path))
        except VehicleDescriptionError as err:
            raise CliError(str(err)) from None
        return cls(name, nominal, layout)

    def ranges(self) -> Any:
        """The fleet ranges around this car (:func:`sideslip_sim.fleet.centred_ranges`)."""
        from sideslip_sim.fleet import centred_ranges

        n = self.nominal
        return centred_ranges(
            mass_kg=n.mass_kg,
            wheelbase_m=n.wheelbase_m,
            front_weight_fraction=n.cg_to_rear_axle_m / n.wheelbase_m,
            cg_height_m=n.cg_height_m,
            track_m=n.track_m,
            stl_per_road_wheel_angle_m_per_rad=n.stl_per_road_wheel_angle_m_per_rad,
            tire_rolling_radius_m=n.tire_rolling_radius_m,
            layout=self.layout,
        )

    def vehicle(self) -> Any:
        """The full car this description stands for (:mod:`sideslip_sim.described_car`)."""
        from sideslip_sim.described_car import described_vehicle
        from sideslip_sim.fleet import FleetError

        try:
            return described_vehicle(name=self.name, layout=self.layout, **self.nominal.to_dict())
        except FleetError as err:
            raise CliError(str(err)) from None

    def ukf_params_yaml(self) -> str:
        """The described car's ``ukf`` params file (what the node's UKF is given)."""
        from sideslip_sim.vehicle import vehicle_record

        from .physics_params import nominal_parameters, params_yaml

        values = nominal_parameters("ukf", vehicle_record(self.vehicle()))
        # The tyres are the fleet's typical ones, not this car's: a model reading the UKF
        # publishes its σ for described files with it (ukf_model.AXLES_FROM).
        values["axles_from"] = "description"
        return params_yaml("ukf", self.name, values, "sideslip-fit from the description")

    def digest(self) -> str:
        text = json.dumps([self.nominal.to_dict(), self.layout], sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


__all__ = ["Description"]
