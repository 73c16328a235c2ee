"""Vehicle files: the shipped ones load; unknown, missing and bad keys are named errors."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from sideslip_sim.vehicle import VehicleFileError, load_vehicle, shipped_vehicles

SEDAN = Path(load_vehicle("paper_sedan").source_path)


def _write(tmp_path: Path, change) -> Path:
    data = yaml.safe_load(SEDAN.read_text())
    change(data)
    path = tmp_path / "vehicle.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_shipped_vehicles_load_and_differ():
    names = shipped_vehicles()
    assert {"paper_sedan", "compact_rwd"} <= set(names)
    sedan, other = load_vehicle("paper_sedan"), load_vehicle("compact_rwd")
    assert sedan.mass_kg == pytest.approx(1155.0)  # Table 1
    assert sedan.wheelbase_m == pytest.approx(2.8)
    assert other.drive_layout != sedan.drive_layout
    assert abs(other.mass_kg - sedan.mass_kg) > 200
    assert sedan.tire_path().is_file() and other.tire_path().is_file()


def test_paper_sedan_matches_table1_as_printed():
    v = load_vehicle("paper_sedan")
    assert v.sprung_mass_kg == 1068.0
    assert v.unsprung_mass_kg == pytest.approx(87.0)
    assert (v.cg_to_front_axle_m, v.cg_to_rear_axle_m, v.cg_height_m) == (0.7209, 2.0791, 0.5373)
    assert v.tire_rolling_radius_m == 0.4673
    assert (v.spring_front_n_per_m, v.spring_rear_n_per_m) == (40000.0, 35000.0)
    assert (v.damper_front_ns_per_m, v.damper_rear_ns_per_m) == (1800.0, 1800.0)


def test_unknown_key_is_an_error_naming_it(tmp_path):
    path = _write(tmp_path, lambda d: d.update(wheel_base_typo_m=2.8))
    with pytest.raises(VehicleFileError, match="wheel_base_typo_m"):
        load_vehicle(path)


def test_missing_key_is_an_error_naming_it(tmp_path):
    path = _write(tmp_path, lambda d: d.pop("yaw_inertia_kgm2"))
    with pytest.raises(VehicleFileError, match="yaw_inertia_kgm2"):
        load_vehicle(path)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("sprung_mass_kg", -5.0, "sprung_mass_kg must be > 0"),
        ("sprung_mass_kg", "heavy", "sprung_mass_kg must be a number"),
        ("drive_layout", "front", "drive_layout must be one of"),
        ("ackermann_fraction", 1.5, "ackermann_fraction must be in"),
        ("roll_center_height_front_m", 0.9, "roll_center_height_front_m"),
    ],
)
def test_implausible_value_is_an_error_naming_the_key(tmp_path, key, value, message):
    path = _write(tmp_path, lambda d: d.update({key: value}))
    with pytest.raises(VehicleFileError, match=message):
        load_vehicle(path)


def test_unknown_shipped_name_lists_the_shipped_ones():
    with pytest.raises(VehicleFileError, match="paper_sedan"):
        load_vehicle("no_such_car")


def test_not_yaml_is_an_error_naming_the_file(tmp_path):
    path = tmp_path / "broken.yaml"
    path.write_text("name: [unclosed\n")
    with pytest.raises(VehicleFileError, match=r"broken\.yaml"):
        load_vehicle(path)
