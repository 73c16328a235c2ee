"""Y_a's scale and bias measured from speed and yaw rate alone: right for a level IMU,
the roll's gravity share for a body-frame one (as the reference-based check finds it),
exactly equivariant to a scale and bias put on Y_a, and no answer without cornering."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_estimator.accelerometer_scale import (
    CHUNK_S,
    SCALE_TOLERANCE,
    AccelerometerScale,
    estimate_scale,
)
from sideslip_sim.generate import generate
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.presets import VehicleRun
from sideslip_sim.vehicle import load_vehicle
from sideslip_training.accelerometer_check import check_accelerometer
from sideslip_training.dataset import Run, load_runs

# Two cars' worth of ordinary corners: both directions, two roads, ~50 s of driving.
DRIVES = (
    Maneuver("sine", "sine_steer", 12.0, 80.0, 0.0, stl_amplitude_m=0.05),
    Maneuver("lane", "double_lane_change", 8.0, 70.0, 0.0),
    Maneuver("sweep", "sweep_steer", 12.0, 60.0, 0.0, stl_amplitude_m=0.04, mu=0.7),
    Maneuver("step", "step_steer", 12.0, 60.0, 0.0, stl_amplitude_m=0.03),
)


@pytest.fixture(scope="module")
def drives(tmp_path_factory: pytest.TempPathFactory) -> dict[str, list[Run]]:
    """The same noisy drives of one car, read level and in the body frame."""
    car = load_vehicle("compact_rwd")
    out = {}
    for frame in ("level", "body"):
        folder = tmp_path_factory.mktemp(frame)
        generate([VehicleRun(car, m) for m in DRIVES], folder, progress=False,
                 imu=ImuMounting(frame=frame))  # fmt: skip
        out[frame] = load_runs([folder])[0]
    return out


def _recorded_as(runs: list[Run], scale: float, bias: float) -> list[SimpleNamespace]:
    out = []
    for r in runs:
        y_a = r.samples.y_a_mps2 * scale + bias
        out.append(SimpleNamespace(samples=dataclasses.replace(r.samples, y_a_mps2=y_a)))
    return out


def test_a_level_imu_measures_a_scale_of_one(drives: dict[str, list[Run]]) -> None:
    got = estimate_scale(drives["level"], fit_bias=True)
    assert got is not None and got.cornering_s > 20.0
    assert got.scale == pytest.approx(1.0, abs=0.005)
    assert abs(got.bias_mps2) < 0.03
    assert got.warning is None


def test_a_body_frame_imu_measures_the_gravity_the_reference_check_finds(
    drives: dict[str, list[Run]],
) -> None:
    got = estimate_scale(drives["body"], fit_bias=True)
    check = check_accelerometer(drives["body"])
    assert got is not None and check is not None
    assert got.scale > 1.0 + SCALE_TOLERANCE  # a compact car rolls: several % of g
    assert got.scale == pytest.approx(check.scale, abs=0.01)
    assert got.warning is not None and f"{got.channel_fix[0]:.4f}" in got.warning


@settings(max_examples=20, deadline=None)
@given(scale=st.floats(0.8, 1.25), bias=st.floats(-0.5, 0.5))
def test_a_scale_and_bias_on_y_a_come_out_exactly(
    drives: dict[str, list[Run]], scale: float, bias: float
) -> None:
    # The fit is linear in Y_a: what is put on it comes out, whatever the car does.
    base = estimate_scale(drives["level"], fit_bias=True)
    got = estimate_scale(_recorded_as(drives["level"], scale, bias), fit_bias=True)
    assert base is not None and got is not None
    assert got.scale == pytest.approx(scale * base.scale, rel=1e-9)
    assert got.bias_mps2 == pytest.approx(scale * base.bias_mps2 + bias, abs=1e-9)
    fix, offset = got.channel_fix
    assert got.scale * fix == pytest.approx(1.0) and offset == pytest.approx(-got.bias_mps2 * fix)


def test_without_the_bias_fit_the_bias_is_zero(drives: dict[str, list[Run]]) -> None:
    got = estimate_scale(drives["level"])
    assert got is not None and got.bias_mps2 == 0.0
    assert got.scale == pytest.approx(1.0, abs=0.005)


def test_the_spread_is_a_jackknife_over_chunks(drives: dict[str, list[Run]]) -> None:
    assert CHUNK_S > max(m.duration_s for m in DRIVES)  # one chunk per drive here
    got = estimate_scale(drives["level"], fit_bias=True)
    assert got is not None and got.chunks == len(DRIVES)
    # Four drives make a rough jackknife (about 1 %), still well inside the 3 % warning.
    assert 0.0 < got.spread < SCALE_TOLERANCE


def test_fewer_chunks_than_a_jackknife_needs_give_no_spread(
    drives: dict[str, list[Run]], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sideslip_estimator.accelerometer_scale as accelerometer_scale

    monkeypatch.setattr(accelerometer_scale, "MIN_CHUNKS", len(DRIVES) + 1)
    got = estimate_scale(drives["level"], fit_bias=True)
    assert got is not None and got.chunks < accelerometer_scale.MIN_CHUNKS
    assert np.isnan(got.spread) and got.scale == pytest.approx(1.0, abs=0.005)


def test_a_gap_inside_a_run_is_not_integrated_over(drives: dict[str, list[Run]]) -> None:
    # The second half of every drive a minute later (a logger paused): the same estimate.
    gapped = []
    for r in drives["level"]:
        stamps = r.samples.stamp_ns.copy()
        stamps[stamps.size // 2 :] += 60 * 10**9
        gapped.append(SimpleNamespace(samples=dataclasses.replace(r.samples, stamp_ns=stamps)))
    whole, cut = (
        estimate_scale(drives["level"], fit_bias=True),
        estimate_scale(gapped, fit_bias=True),
    )
    assert whole is not None and cut is not None
    assert cut.scale == pytest.approx(1.0, abs=0.01)
    assert cut.cornering_s == pytest.approx(whole.cornering_s, rel=0.02)  # not the gap


def test_holes_in_a_run_end_a_stretch_instead_of_being_integrated(
    drives: dict[str, list[Run]],
) -> None:
    holed = []
    for r in drives["level"]:
        y = r.samples.y_a_mps2.copy()
        y[len(y) // 2 : len(y) // 2 + 40] = np.nan
        holed.append(SimpleNamespace(samples=dataclasses.replace(r.samples, y_a_mps2=y)))
    got = estimate_scale(holed, fit_bias=True)
    assert got is not None and np.isfinite(got.scale)
    assert got.scale == pytest.approx(1.0, abs=0.005)


def test_straight_driving_gives_no_estimate(tmp_path: Path) -> None:
    car = load_vehicle("compact_rwd")
    straight = Maneuver("straight", "straight", 30.0, 80.0, 0.0)
    generate([VehicleRun(car, straight)], tmp_path, progress=False)
    runs, report = load_runs([tmp_path], require_truth=False)
    assert estimate_scale(runs) is None
    assert report.accelerometer_scale is None


def test_the_data_report_says_a_wrong_scale_without_a_reference(tmp_path: Path) -> None:
    car = load_vehicle("compact_rwd")
    generate([VehicleRun(car, m) for m in DRIVES], tmp_path, progress=False,
             imu=ImuMounting(frame="body"))  # fmt: skip
    # No reference used: the reference-based check cannot run, this one does.
    _, report = load_runs([tmp_path], require_truth=False)
    assert report.accelerometer is None
    got = report.accelerometer_scale
    assert isinstance(got, AccelerometerScale) and got.warning is not None
    assert got.warning in report.lines and "yaw rate and speed" in got.warning
