"""sideslip-fit: a car's description → a fleet around it → a fitted, tested model."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import pytest
import yaml

from sideslip_msgs_py.artifact import read_artifact
from sideslip_msgs_py.fleet_envelope import FleetEnvelope
from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_sim.fleet import sample_fleet
from sideslip_training import observer
from sideslip_training.fit import Description, default_start, main
from sideslip_training.init_model import resolve

TORCH_ON_EVERY_CORE = True  # fits and scorings of shipped models (conftest)

SEDAN = {
    "name": "my_sedan",
    "mass_kg": 1550.0,
    "wheelbase_m": 2.85,
    "cg_to_front_axle_m": 1.368,
    "cg_height_m": 0.54,
    "track_m": 1.57,
    "stl_per_road_wheel_angle_m_per_rad": 1.7,
    "tire_rolling_radius_m": 0.32,
    "drive_layout": "rwd",
}


def test_the_fleet_around_a_car_keeps_what_its_owner_gave() -> None:
    n = VehicleDescription.from_mapping({k: v for k, v in SEDAN.items() if k != "drive_layout"})
    ranges = Description("my_sedan", n, "rwd").ranges()
    cars = sample_fleet(6, 3, prefix="t", ranges=ranges).vehicles
    for car in cars:
        d = VehicleDescription.from_mapping(
            {k: v for k, v in car.__dict__.items() if k != "source_path"}
        )
        assert abs(d.mass_kg / n.mass_kg - 1) <= 0.05 + 1e-9
        assert abs(d.wheelbase_m / n.wheelbase_m - 1) <= 0.01 + 1e-9
        assert abs(d.front_weight_fraction - n.front_weight_fraction) <= 0.02 + 1e-9
        assert car.drive_layout == "rwd"
    # What the owner cannot know is spread: the cars are not copies of one another.
    assert len({round(c.yaw_inertia_kgm2, 3) for c in cars}) == len(cars)


def test_a_fit_from_a_description_writes_a_tested_model_and_its_card(
    tmp_path: Path, capsys
) -> None:
    desc = tmp_path / "sedan.yaml"
    desc.write_text(yaml.safe_dump(SEDAN))
    out = tmp_path / "sedan.safetensors"
    args = ["--vehicle", str(desc), "--out", str(out), "--cars", "3", "--test-runs", "2"]
    args += ["--device", "cpu", "--quiet"]
    assert main(args) == 0
    meta = read_artifact(out)[1]
    assert meta.provenance["init"] == "fleet_lstm_paper.safetensors"
    card = out.with_suffix(".md").read_text()
    assert "my_sedan" in card and "| β = 0 |" in card and "(sedan)" in card
    assert "drive layout: rwd" in card
    assert "sideslip-identify-axles" not in card  # the paper model reads no UKF
    # Interrupted after the data: the same command picks the data up again.
    out.unlink()
    capsys.readouterr()
    assert main([a for a in args if a != "--quiet"]) == 0
    assert "already generated (resumed)" in capsys.readouterr().err
    # Refusals: an existing --out, a description that is not one.
    assert main(args) == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({**SEDAN, "drive_layout": "6wd"}))
    assert main(["--vehicle", str(bad), "--out", str(tmp_path / "x.safetensors")]) == 2
    assert "drive_layout" in capsys.readouterr().err


def test_the_description_names_a_missing_key(tmp_path: Path) -> None:
    from sideslip_training.cli_errors import CliError

    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump({k: v for k, v in SEDAN.items() if k != "track_m"}))
    with pytest.raises(CliError, match="track_m"):
        Description.load(path)


def test_a_measurable_fit_trains_the_ukf_residual_on_the_described_car(tmp_path: Path) -> None:
    desc = tmp_path / "sedan.yaml"
    desc.write_text(yaml.safe_dump(SEDAN))
    out = tmp_path / "sedan.safetensors"
    # The start model given as a file (a user's own, here a copy of the shipped one).
    start = tmp_path / "my_start.safetensors"
    shutil.copyfile(resolve(default_start("measurable", bags=False)), start)
    args = ["--vehicle", str(desc), "--out", str(out), "--cars", "1", "--test-runs", "1"]
    args += ["--max-epochs", "1", "--features", "measurable", "--device", "cpu", "--quiet"]
    assert main([*args, "--init", str(start)]) == 0
    meta = read_artifact(out)[1]
    assert meta.provenance["init"] == "my_start.safetensors"
    # The ukf file beside the model is the described car's, and the model knows that
    # car as one of its training cars: a node given the file runs the network.
    ukf = yaml.safe_load(out.with_suffix(".ukf.yaml").read_text())
    described = observer.params_of_vehicle(_as_recorded(Description.load(desc).vehicle()))
    assert ukf == {**described, "axles_from": "description"}  # the fleet's typical tyres
    assert not FleetEnvelope.from_dict(meta.envelope).outside(ukf, "described car")
    card = out.with_suffix(".md").read_text()
    assert f"pso_lstm.observer_params_file:={out.with_suffix('.ukf.yaml')}" in card
    assert "| UKF |" in card and "(my_start)" in card
    # A user with labelled recordings is pointed to the car's own axles.
    assert "sideslip-identify-axles --vehicle" in card


def test_a_description_alone_starts_from_the_model_trained_on_described_cars_too() -> None:
    # Recordings identify the axles (a nearly right filter): the mean of the models
    # trained on true files and on true and described ones. A description alone leaves
    # the filter's tyres typical: the model that saw described cars' filters in
    # training, with the same inputs.
    assert default_start("measurable", bags=False) == "fleet_ukf_described"
    assert default_start("measurable", bags=True) == "fleet_ukf_ensemble"
    assert default_start("paper", bags=False) == default_start("paper", bags=True)
    described = read_artifact(resolve("fleet_ukf_described"))[1]
    measurable = read_artifact(resolve("fleet_ukf_measurable"))[1]
    assert described.features == measurable.features and described.prior == "ukf"
    assert "--car mixed" in described.provenance["command"]


@pytest.mark.parametrize(
    ("features", "start", "says"),
    [
        ("measurable", "fleet_lstm_paper", "reads Y_v"),
        ("paper", "fleet_ukf_measurable", "reads the UKF's outputs"),
        ("paper", "no_such_model", "no such model file"),
    ],
)
def test_a_start_model_that_does_not_fit_the_features_is_refused_before_simulating(
    tmp_path: Path, capsys, features: str, start: str, says: str
) -> None:
    desc = tmp_path / "sedan.yaml"
    desc.write_text(yaml.safe_dump(SEDAN))
    out = tmp_path / "sedan.safetensors"
    argv = ["--vehicle", str(desc), "--out", str(out), "--features", features, "--init", start]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert says in err and f"--init {start}" in err and len(err.splitlines()) == 1
    assert not out.with_suffix(".fit").exists()


def _as_recorded(car) -> dict:
    return {k: v for k, v in dataclasses.asdict(car).items() if k != "source_path"}
