"""Y_a's scale measured sample by sample: the offline fit's answer at any rate, stretches
cut where the driving stops, a remounted IMU noticed, and a state that survives a
restart (a JSON round trip) or is refused whole."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from kinematic_drive import kinematic_drive

from sideslip_estimator.accelerometer_scale import (
    CHUNK_S,
    estimate_scale,
    solve,
    stretch_chunks,
)
from sideslip_estimator.online_accelerometer_scale import (
    RECENT_CHUNKS,
    OnlineAccelerometerScale,
    StateError,
)
from sideslip_msgs_py.messages import NS_PER_S


def measured(*drives, **kwargs) -> OnlineAccelerometerScale:
    online = OnlineAccelerometerScale(**kwargs)
    for drive in drives:
        for sample in drive.samples():
            online.add(*sample)
    online.end_stretch()
    return online


def test_a_scale_and_bias_on_y_a_come_back() -> None:
    online = measured(kinematic_drive(300.0, scale=1.1, bias=0.05))
    est = online.estimate
    assert est is not None and est.chunks == 5
    assert est.scale == pytest.approx(1.1, abs=0.002)
    assert est.bias_mps2 == pytest.approx(0.05, abs=0.01)
    assert 0.0 < est.spread < 0.002


def test_it_fits_as_the_offline_fit_over_the_whole_stretch() -> None:
    drive = kinematic_drive(250.0, scale=1.12, bias=-0.03, seed=3)
    t = (drive.stamp_ns - drive.stamp_ns[0]) / NS_PER_S
    # The offline fit cut where the online one cuts: every CHUNK_S from the start, the
    # last chunk taking what is left (under CHUNK_S + MARGIN_S: 70 s).
    chunk = np.minimum(np.floor(t / CHUNK_S), 3).astype(np.int64)
    offline = solve(
        stretch_chunks(t, drive.x_v_mps, drive.yaw_rate_radps, drive.y_a_mps2, chunk,
                       fit_bias=True), fit_bias=True)  # fmt: skip
    online = measured(drive).estimate
    assert offline is not None and online is not None
    assert online.chunks == offline.chunks == 4
    assert online.scale == pytest.approx(offline.scale, abs=3e-4)
    assert online.bias_mps2 == pytest.approx(offline.bias_mps2, abs=2e-3)
    assert online.cornering_s == pytest.approx(offline.cornering_s, rel=0.01)


@settings(max_examples=6, deadline=None)
@given(rate_hz=st.sampled_from([50.0, 100.0, 200.0, 1000.0]))
def test_any_input_rate_gives_the_scale(rate_hz: float) -> None:
    est = measured(kinematic_drive(130.0, scale=1.08, seed=5, rate_hz=rate_hz)).estimate
    assert est is not None
    assert est.scale == pytest.approx(1.08, abs=2e-3)


def test_drives_as_separate_stretches_give_the_offline_answer() -> None:
    from types import SimpleNamespace

    drives = [kinematic_drive(25.0, scale=1.1, seed=s, start_ns=s * 100 * NS_PER_S)
              for s in range(6)]  # fmt: skip
    runs = [
        SimpleNamespace(samples=SimpleNamespace(
            stamp_ns=d.stamp_ns, x_v_mps=d.x_v_mps, yaw_rate_radps=d.yaw_rate_radps,
            y_a_mps2=d.y_a_mps2)) for d in drives
    ]  # fmt: skip
    offline = estimate_scale(runs, fit_bias=True)
    online = measured(*drives).estimate
    assert offline is not None and online is not None
    assert online.chunks == offline.chunks == 6  # one per drive: the gaps cut them
    assert online.scale == pytest.approx(offline.scale, abs=5e-4)


def test_a_gap_a_stamp_going_back_and_a_nan_end_the_stretch() -> None:
    drive = kinematic_drive(90.0, scale=1.1)
    samples = drive.samples()
    online = OnlineAccelerometerScale(max_gap_s=0.5)
    for i, (stamp, u, r, y) in enumerate(samples):
        if i == 9000:
            online.add(stamp, u, r, math.nan)  # a hole: ends the first stretch
            continue
        shift = NS_PER_S if i > 18000 else 0  # a 1-s gap: ends the second
        online.add(stamp + shift, u, r, y)
    online.end_stretch()
    assert online.completed == 3
    est = online.estimate
    assert est is not None and math.isfinite(est.scale)
    assert est.scale == pytest.approx(1.1, abs=0.01)


@pytest.mark.parametrize("samples", [2, 12, 40, 100, 160, 600])
def test_a_stretch_too_short_to_filter_is_dropped_without_an_error(samples: int) -> None:
    online = OnlineAccelerometerScale(max_gap_s=0.1)
    drive = kinematic_drive(samples / 400.0, scale=1.1)
    for sample in drive.samples():
        online.add(*sample)
    online.add(drive.stamp_ns[-1] + NS_PER_S, 20.0, 0.1, 2.0)  # after a gap
    online.end_stretch()
    assert online.estimate is None


def test_straight_driving_gives_no_estimate() -> None:
    online = OnlineAccelerometerScale()
    for k in range(400 * 200):
        online.add(k * 2_500_000, 25.0, 0.0, 0.01)
    online.end_stretch()
    assert online.estimate is None


def test_a_remounted_imu_is_noticed_and_the_old_mounting_forgotten() -> None:
    before = [kinematic_drive(CHUNK_S, scale=1.12, seed=s, rate_hz=100.0,
                              start_ns=s * 100 * NS_PER_S) for s in range(12)]  # fmt: skip
    after = [kinematic_drive(CHUNK_S, scale=1.0, seed=s, rate_hz=100.0,
                             start_ns=s * 100 * NS_PER_S) for s in range(20, 26)]  # fmt: skip
    online = measured(*before, *after)
    assert online.remounts == 1
    assert len(online.chunks) == RECENT_CHUNKS + 1
    assert online.estimate is not None
    assert online.estimate.scale == pytest.approx(1.0, abs=0.003)


def test_one_mounting_throughout_is_no_remount_and_memory_is_bounded() -> None:
    drives = [kinematic_drive(CHUNK_S, scale=1.05, seed=s, rate_hz=100.0,
                              start_ns=s * 100 * NS_PER_S) for s in range(14)]  # fmt: skip
    online = measured(*drives, memory_chunks=10)
    assert online.remounts == 0
    assert len(online.chunks) == 10 and online.completed == 14


@settings(max_examples=10, deadline=None)
@given(seconds=st.floats(40.0, 200.0), scale=st.floats(0.9, 1.2))
def test_the_state_survives_a_json_round_trip(seconds: float, scale: float) -> None:
    online = measured(kinematic_drive(seconds, scale=scale, rate_hz=50.0))
    again = OnlineAccelerometerScale()
    again.restore(json.loads(json.dumps(online.state())))
    assert len(again.chunks) == len(online.chunks)
    if online.estimate is None:
        assert again.estimate is None
    else:
        assert again.estimate == online.estimate


@pytest.mark.parametrize(
    ("change", "named"),
    [
        (lambda s: s.update(version=99), "version-1"),
        (lambda s: s.update(fit_bias=False), "fit_bias"),
        (lambda s: s["chunks"][1].update(xtx=[[1.0]]), "chunk 1: sums of shape"),
        (lambda s: s["chunks"][0].update(xty=[0.0, math.inf, 0.0, 0.0]), "non-finite"),
        (lambda s: s["chunks"][0].pop("samples"), "chunk 0"),
    ],
)
def test_a_bad_state_is_refused_whole(change, named: str) -> None:
    online = measured(kinematic_drive(200.0, scale=1.1, rate_hz=50.0))
    state = online.state()
    target = OnlineAccelerometerScale()
    target.restore(state)
    kept = target.estimate
    broken = json.loads(json.dumps(state))
    change(broken)
    with pytest.raises(StateError, match=named):
        target.restore(broken)
    assert target.estimate == kept and len(target.chunks) == len(state["chunks"])
