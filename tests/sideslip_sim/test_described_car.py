"""The car a short description stands for: the given values kept, the fleet's typical
rest, a plausible car, and its ukf params file from the CLI."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_estimator.backends import UkfParams
from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_sim.described_car import described_vehicle
from sideslip_sim.fleet import FleetError, FleetRanges, vehicle_digest
from sideslip_sim.held_out import held_out_vehicles
from sideslip_sim.plausibility import plausibility_problems
from sideslip_sim.tire import load_tire
from sideslip_sim.ukf_params import main

WAGON = {
    "mass_kg": 1720.0,
    "wheelbase_m": 2.79,
    "cg_to_front_axle_m": 1.19,
    "cg_height_m": 0.58,
    "track_m": 1.58,
    "stl_per_road_wheel_angle_m_per_rad": 1.55,
    "tire_rolling_radius_m": 0.33,
}


def _description(car) -> VehicleDescription:
    return VehicleDescription.from_mapping(
        {k: v for k, v in dataclasses.asdict(car).items() if k != "source_path"}
    )


def _close(a: VehicleDescription, b: VehicleDescription) -> None:
    for key, value in a.to_dict().items():
        assert b.value(key) == pytest.approx(value, rel=1e-5), key


@pytest.mark.parametrize("name", sorted(held_out_vehicles()))
def test_a_described_car_keeps_the_description_and_is_plausible(name: str) -> None:
    car = held_out_vehicles()[name]
    desc = _description(car)
    done = described_vehicle(name=name, layout=car.drive_layout, **desc.to_dict())
    _close(desc, _description(done))
    assert done.drive_layout == car.drive_layout
    assert not plausibility_problems(done, load_tire(str(done.tire_path())))
    # A nominal guess, not the car: what the description does not say differs.
    assert vehicle_digest(done) != vehicle_digest(car)


@settings(max_examples=25, deadline=None)
@given(
    mass=st.floats(1000.0, 2500.0),
    wheelbase=st.floats(2.4, 3.1),
    front=st.floats(0.40, 0.63),
    cg_height=st.floats(0.45, 0.70),
)
def test_any_fleet_like_description_completes_to_the_same_plausible_car_every_time(
    mass: float, wheelbase: float, front: float, cg_height: float
) -> None:
    values = {
        **WAGON,
        "mass_kg": mass,
        "wheelbase_m": wheelbase,
        "cg_to_front_axle_m": (1.0 - front) * wheelbase,
        "cg_height_m": cg_height,
    }
    car = described_vehicle(name="x", **values)
    assert vehicle_digest(car) == vehicle_digest(described_vehicle(name="x", **values))
    assert car.drive_layout == ("fwd" if front >= 0.55 else "rwd")
    assert not plausibility_problems(car, load_tire(str(car.tire_path())))
    # The unknowns sit mid-fleet: a dynamic index of 1.0.
    a, b = car.cg_to_front_axle_m, car.cg_to_rear_axle_m
    mid = sum(FleetRanges().dynamic_index) / 2
    assert car.yaw_inertia_kgm2 == pytest.approx(mid * car.mass_kg * a * b, rel=1e-4)


def test_a_description_no_passenger_car_matches_is_refused_with_the_reason() -> None:
    with pytest.raises(FleetError, match="static stability factor"):
        described_vehicle(name="tall", **{**WAGON, "cg_height_m": 1.6})
    with pytest.raises(FleetError, match="between the axles"):
        described_vehicle(name="bad", **{**WAGON, "cg_to_front_axle_m": 3.0})
    with pytest.raises(FleetError, match="layout"):
        described_vehicle(name="bad", layout="6wd", **WAGON)


def test_the_cli_writes_the_described_cars_ukf_file(tmp_path: Path, capsys) -> None:
    path = tmp_path / "my_car.yaml"
    path.write_text(yaml.safe_dump({**WAGON, "name": "my_car", "drive_layout": "rwd"}))
    assert main([str(path), "--description"]) == 0
    params = yaml.safe_load(capsys.readouterr().out)
    assert params["name"] == "my_car"
    assert params["mass_kg"] == pytest.approx(WAGON["mass_kg"], rel=1e-5)
    # The estimator's back-end accepts it as it is, and knows its tyres are a guess.
    assert UkfParams.from_mapping(params, "cli").axles_from == "description"
    path.write_text(yaml.safe_dump({**WAGON, "cg_height_m": 1.6}))
    assert main([str(path), "--description"]) == 2
    assert "static stability factor" in capsys.readouterr().err
