"""The estimator's own Y_a check: measured from the accepted samples, applied only in
mode ``apply`` and only once confident, reported in the status, and kept in a state file
that a crash cannot half-write and a broken one cannot stop the estimator over."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from kinematic_drive import kinematic_drive

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.imu_scale import ImuScale, ImuScaleParams
from sideslip_estimator.inputs import X_V, Y_A, YAW_RATE
from sideslip_estimator.online_accelerometer_scale import OnlineAccelerometerScale
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields

SCALE, BIAS = 1.12, 0.08  # a body-frame IMU's gravity share and a roll error's bias


def rows_of(drive) -> list[tuple[np.ndarray, int]]:
    out = []
    for stamp, u, r, y in drive.samples():
        row = np.zeros(len(CHANNELS))
        row[X_V], row[YAW_RATE], row[Y_A] = u, r, y
        out.append((row, stamp))
    return out


def fed(imu_scale: ImuScale, drive) -> list[float]:
    """Y_a of every row after ``imu_scale`` saw it."""
    out = []
    for row, stamp in rows_of(drive):
        imu_scale.feed(row, stamp)
        out.append(float(row[Y_A]))
    return out


def test_report_measures_and_leaves_y_a_as_recorded() -> None:
    scale = ImuScale(ImuScaleParams(mode="report"), max_gap_s=0.1)
    drive = kinematic_drive(250.0, scale=SCALE, bias=BIAS)
    assert fed(scale, drive) == drive.y_a_mps2.tolist()
    assert scale.confident is not None and scale.applied is None
    warnings, values = scale.report()
    assert any("imu_scale.mode apply" in w for w in warnings)
    assert values["imu_scale_applied"] == "no"
    assert float(values["imu_scale"]) == pytest.approx(SCALE, abs=0.003)


def test_apply_corrects_y_a_once_confident_and_not_before() -> None:
    scale = ImuScale(ImuScaleParams(mode="apply"), max_gap_s=0.1)
    drive = kinematic_drive(250.0, scale=SCALE, bias=BIAS)
    got = np.asarray(fed(scale, drive))
    t = (drive.stamp_ns - drive.stamp_ns[0]) * 1e-9
    # Three chunks (a jackknife) close once 3·60 + 10 s have arrived.
    before, after = t < 190.0, t > 191.0
    assert np.array_equal(got[before], drive.y_a_mps2[before])
    err = got[after] - drive.a_y_mps2[after]
    assert abs(err.mean()) < 0.01
    assert np.abs(err).mean() < 0.06  # the sensor's noise (0.05 m/s²), scaled down
    as_recorded = drive.y_a_mps2[after] - drive.a_y_mps2[after]
    assert np.abs(as_recorded).mean() > 2 * np.abs(err).mean()
    warnings, values = scale.report()
    assert values["imu_scale_applied"] == "yes" and not warnings


def test_no_correction_while_the_spread_is_over_max_spread() -> None:
    scale = ImuScale(ImuScaleParams(mode="apply", max_spread=1e-6), max_gap_s=0.1)
    drive = kinematic_drive(250.0, scale=SCALE)
    assert fed(scale, drive) == drive.y_a_mps2.tolist()
    assert scale.online.estimate is not None and scale.applied is None
    assert "spread over 1e-06" in scale.line()


def test_a_remount_is_reported_once() -> None:
    scale = ImuScale(ImuScaleParams(mode="apply"), max_gap_s=0.1)
    for s in range(6):
        fed(scale, kinematic_drive(60.0, scale=1.12, seed=s, rate_hz=100.0, start_ns=s * 10**11))
    for s in range(6):
        fed(scale, kinematic_drive(60.0, scale=1.0, seed=9 + s, rate_hz=100.0,
                                   start_ns=(10 + s) * 10**11))  # fmt: skip
    scale.online.end_stretch()
    warnings, values = scale.report()
    assert any("remounted" in w for w in warnings) and values["imu_scale_remounts"] == "1"
    assert not any("remounted" in w for w in scale.report()[0])


def test_the_state_file_is_kept_and_restored(tmp_path: Path) -> None:
    path = tmp_path / "imu_scale.json"
    params = ImuScaleParams(mode="apply", state_file=str(path))
    first = ImuScale(params, max_gap_s=0.1)
    assert "no state" in (first.load() or "")
    fed(first, kinematic_drive(100.0, scale=SCALE, bias=BIAS))
    assert first.save() is None and path.exists()
    written = path.stat().st_mtime_ns
    assert first.save() is None and path.stat().st_mtime_ns == written  # nothing new
    assert first.save(final=True) is None  # the open stretch: a second chunk
    assert len(json.loads(path.read_text())["chunks"]) == 2
    fed(first, kinematic_drive(70.0, scale=SCALE, bias=BIAS, seed=2, start_ns=10**13))
    first.save(final=True)
    again = ImuScale(params, max_gap_s=0.1)
    assert "3 chunk(s) restored" in (again.load() or "")
    assert again.applied == first.applied is not None
    # A restored car is corrected from its first sample.
    drive = kinematic_drive(5.0, scale=SCALE, bias=BIAS, seed=4)
    got = np.asarray(fed(again, drive))
    assert np.abs(got - drive.a_y_mps2).mean() < 0.06


def test_a_broken_state_file_is_reported_and_measuring_starts_afresh(tmp_path: Path) -> None:
    path = tmp_path / "imu_scale.json"
    path.write_text('{"version": 1, "fit_bias": true, "chunks": [{"xtx": "oops"}]}')
    scale = ImuScale(ImuScaleParams(mode="apply", state_file=str(path)), max_gap_s=0.1)
    line = scale.load() or ""
    assert "unreadable" in line and str(path) in line
    assert scale.online.estimate is None and not scale.online.chunks
    path.write_text("not json")
    assert "unreadable" in (scale.load() or "")


def test_a_state_file_that_cannot_be_written_is_an_error_line(tmp_path: Path) -> None:
    path = tmp_path / "no_such_folder" / "imu_scale.json"
    scale = ImuScale(ImuScaleParams(mode="report", state_file=str(path)), max_gap_s=0.1)
    fed(scale, kinematic_drive(70.0, scale=SCALE))
    line = scale.save(final=True) or ""
    assert "cannot write state file" in line and str(path) in line


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"mode": "fix"}, "imu_scale.mode"),
        ({"max_spread": math.nan}, "imu_scale.max_spread"),
        ({"max_spread": 0.0}, "imu_scale.max_spread"),
        ({"memory_chunks": 3}, "imu_scale.memory_chunks"),
    ],
)
def test_bad_parameters_are_named(change: dict, named: str) -> None:
    with pytest.raises(ValueError, match=named):
        ImuScaleParams(**change)


def test_the_estimator_windows_the_corrected_y_a(tmp_path: Path) -> None:
    # A car that has driven before: its state restored, its Y_a corrected at once.
    measured = OnlineAccelerometerScale()
    for sample in kinematic_drive(200.0, scale=SCALE, bias=BIAS).samples():
        measured.add(*sample)
    measured.end_stretch()
    path = tmp_path / "state.json"
    path.write_text(json.dumps(measured.state()))
    imu_scale = ImuScale(ImuScaleParams(mode="apply", state_file=str(path)), max_gap_s=0.1)
    imu_scale.load()
    fix = imu_scale.applied
    assert fix is not None
    est = Estimator(create_backend("kinematic", {}, 10), EstimatorParams(10), imu_scale)
    drive = kinematic_drive(1.0, scale=SCALE, bias=BIAS, seed=7)
    for stamp, u, r, y in drive.samples():
        est.on_twist("/vehicle/twist", TwistFields(stamp, u, 0.5))
        est.on_steering("/vehicle/steering", SteeringFields(stamp, 0.01, 0.0))
        est.on_imu("/vehicle/imu", ImuFields(stamp, 0.1, y, r))
    windowed = est.window.rows()[:, Y_A]
    np.testing.assert_allclose(windowed, drive.y_a_mps2[-10:] * fix[0] + fix[1])
