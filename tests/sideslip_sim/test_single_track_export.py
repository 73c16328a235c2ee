"""`python -m sideslip_sim.single_track VEHICLE`: the estimator's single_track parameters
of a vehicle as YAML that the estimator loads, and one-line errors with exit code 2."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from sideslip_estimator.backends import SingleTrackParams, create_backend
from sideslip_sim.single_track import SingleTrack, estimator_parameters, main
from sideslip_sim.tire import load_tire
from sideslip_sim.vehicle import load_vehicle


def test_cli_prints_yaml_that_the_estimator_loads(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "sideslip_sim.single_track", "paper_sedan"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith("# single-track parameters of paper_sedan")
    params = SingleTrackParams.from_mapping(yaml.safe_load(proc.stdout), "stdout")
    assert params.name == "paper_sedan"
    # Saved to a file, it is a valid single_track.params_file.
    path = tmp_path / "paper_sedan.yaml"
    path.write_text(proc.stdout)
    backend = create_backend("single_track", {"params_file": str(path)}, 100)
    assert backend.params == params


def test_exported_numbers_are_the_linear_model_of_the_vehicle() -> None:
    vehicle = load_vehicle("compact_rwd")
    tire = load_tire(str(vehicle.tire_path()))
    model = SingleTrack.from_vehicle(vehicle, tire)
    p = estimator_parameters(vehicle, tire)
    assert p["name"] == "compact_rwd"
    assert p["mass_kg"] == vehicle.mass_kg and p["yaw_inertia_kgm2"] == vehicle.yaw_inertia_kgm2
    assert p["cg_to_front_axle_m"] == model.a_m and p["cg_to_rear_axle_m"] == model.b_m
    assert p["cornering_stiffness_front_n_per_rad"] == pytest.approx(model.c_front_n_per_rad, 1e-5)
    assert p["cornering_stiffness_rear_n_per_rad"] == pytest.approx(model.c_rear_n_per_rad, 1e-5)
    assert p["stl_per_road_wheel_angle_m_per_rad"] == vehicle.stl_per_road_wheel_angle_m_per_rad


def test_main_with_a_vehicle_path_prints_its_parameters(capsys: pytest.CaptureFixture) -> None:
    vehicle = load_vehicle("compact_rwd")
    assert main([vehicle.source_path]) == 0
    out = capsys.readouterr().out
    assert yaml.safe_load(out)["name"] == "compact_rwd"


def test_unknown_vehicle_exits_2_with_one_line_naming_the_shipped_ones(
    capsys: pytest.CaptureFixture,
) -> None:
    assert main(["hovercraft"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:")
    assert "hovercraft" in lines[0] and "paper_sedan" in lines[0]


def test_missing_vehicle_file_exits_2(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    assert main([str(tmp_path / "car.yaml")]) == 2
    assert "car.yaml" in capsys.readouterr().err


def test_cli_exit_code_for_an_unknown_vehicle_is_2() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "sideslip_sim.single_track", "hovercraft"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert "hovercraft" in proc.stderr and "Traceback" not in proc.stderr
