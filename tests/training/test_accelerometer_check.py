"""The recorded Y_a checked against the reference: a body-frame IMU, a unit or a sign gone
wrong is said in the data report of every tool, a right IMU passes silently."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from sideslip_msgs_py.bag import read_bag, write_bag
from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_sim.generate import generate
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.presets import VehicleRun
from sideslip_sim.vehicle import load_vehicle
from sideslip_training.accelerometer_check import SCALE_TOLERANCE, check_accelerometer
from sideslip_training.dataset import load_runs

DRIVES = (
    Maneuver("sine", "sine_steer", 8.0, 80.0, 0.0, stl_amplitude_m=0.05),
    Maneuver("lane", "double_lane_change", 8.0, 70.0, 0.0),
    Maneuver("sweep", "sweep_steer", 8.0, 60.0, 0.0, stl_amplitude_m=0.04, mu=0.7),
)


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The same three noisy drives of one car, read level and in the body frame."""
    car = load_vehicle("compact_rwd")
    out = {}
    for frame in ("level", "body"):
        folder = tmp_path_factory.mktemp(frame)
        runs = [VehicleRun(car, m) for m in DRIVES]
        generate(runs, folder, progress=False, imu=ImuMounting(frame=frame))
        out[frame] = folder
    return out


def test_a_level_imu_passes_with_a_scale_near_one(drives: dict[str, Path]) -> None:
    _, report = load_runs([drives["level"]])
    check = report.accelerometer
    assert check is not None and check.samples > 2000
    assert abs(check.scale - 1.0) < SCALE_TOLERANCE / 3
    assert check.warning is None
    assert not any("Y_a is" in line for line in report.lines)


def test_a_body_frame_imu_is_reported_with_the_fix(drives: dict[str, Path]) -> None:
    _, report = load_runs([drives["body"]])
    check = report.accelerometer
    assert check is not None and check.scale > 1.0 + SCALE_TOLERANCE
    (line,) = [line for line in report.lines if "Y_a is" in line]
    assert "body frame" in line and "imu: {frame: body" in line
    assert f"scale y_a_mps2 by {1.0 / check.scale:.3f}" in line
    assert line in str(report)


@pytest.mark.parametrize(
    ("factor", "says"),
    [(-1.0, "sign is reversed"), (1.0 / 9.80665, "looks like g"), (0.8, "reference's frame")],
)
def test_a_unit_or_sign_gone_wrong_is_named(
    drives: dict[str, Path], tmp_path: Path, factor: float, says: str
) -> None:
    for bag in sorted(p for p in drives["level"].iterdir() if p.is_dir()):
        contents = read_bag(bag)
        s = contents.samples
        wrong = dataclasses.replace(s, y_a_mps2=s.y_a_mps2 * factor)
        write_bag(tmp_path / bag.name, wrong, sigma=SensorNoiseSigma.paper(),
                  run_metadata=contents.run_metadata)  # fmt: skip
    runs, report = load_runs([tmp_path])
    check = check_accelerometer(runs)
    assert check is not None and check.scale == pytest.approx(factor, rel=0.02)
    assert check.warning is not None and says in check.warning
    assert check.warning in report.lines


def test_no_reference_or_no_cornering_gives_no_check(drives: dict[str, Path]) -> None:
    from sideslip_training.dataset import slice_samples

    runs, _ = load_runs([drives["level"]])
    assert check_accelerometer(runs[:0]) is None
    # One second of the start: too little cornering to tell a scale.
    short = [dataclasses.replace(r, samples=slice_samples(r.samples, 0, 400)) for r in runs]
    assert check_accelerometer(short) is None
    no_reference = [
        dataclasses.replace(
            r,
            samples=dataclasses.replace(
                r.samples, truth_v_x_mps=None, truth_v_y_mps=None, truth_yaw_rate_radps=None
            ),
        )
        for r in runs
    ]
    assert check_accelerometer(no_reference) is None
