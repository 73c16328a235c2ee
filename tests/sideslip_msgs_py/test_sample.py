"""Sample records, columnar arrays and noise σ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.errors import SampleArraysError
from sideslip_msgs_py.sample import (
    GroundTruth,
    SampleArrays,
    SensorNoiseSigma,
    VehicleSample,
)

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@st.composite
def sample_lists(draw: st.DrawFn) -> list[VehicleSample]:
    n = draw(st.integers(0, 20))
    stamps = sorted(draw(st.sets(st.integers(0, 2**62), min_size=n, max_size=n)))
    with_truth = draw(st.booleans())
    out = []
    for stamp in stamps:
        truth = GroundTruth(draw(finite), draw(finite), draw(finite)) if with_truth else None
        out.append(VehicleSample(stamp, *(draw(finite) for _ in range(7)), truth=truth))
    return out


@settings(deadline=None)
@given(sample_lists())
def test_samples_to_arrays_and_back_is_exact(samples: list[VehicleSample]) -> None:
    arrays = SampleArrays.from_samples(samples)
    assert len(arrays) == len(samples)
    assert [arrays.row(i) for i in range(len(arrays))] == samples


def test_arrays_reject_stamps_that_do_not_increase() -> None:
    z = np.zeros(3)
    with pytest.raises(SampleArraysError, match=r"stamp_ns must be strictly increasing: row 2"):
        SampleArrays(np.array([0, 5, 5]), z, z, z, z, z, z, z)


def test_arrays_reject_unequal_lengths_naming_the_channel() -> None:
    z = np.zeros(3)
    with pytest.raises(SampleArraysError, match=r"SampleArrays.stl_m has 2 rows"):
        SampleArrays(np.arange(3), z, z, z, z, z, np.zeros(2), z)


def test_arrays_reject_partial_truth_and_float_stamps() -> None:
    z = np.zeros(2)
    with pytest.raises(SampleArraysError, match="truth channels must be given together"):
        SampleArrays(np.arange(2), z, z, z, z, z, z, z, truth_v_x_mps=z)
    with pytest.raises(SampleArraysError, match="stamp_ns must hold integers"):
        SampleArrays(np.array([0.0, 1.0]), z, z, z, z, z, z, z)


def test_arrays_are_read_only_and_leave_caller_arrays_writable() -> None:
    stamps, z = np.arange(2, dtype=np.int64), np.zeros(2)
    arrays = SampleArrays(stamps, z, z, z, z, z, z, z)
    with pytest.raises(ValueError, match="read-only"):
        arrays.stl_m[0] = 1.0
    stamps[0] = -1  # the caller's array stays writable (the record holds a view)
    assert stamps.flags.writeable


def test_beta_is_atan2_of_lateral_over_longitudinal_velocity() -> None:
    truth = GroundTruth(v_x_mps=10.0, v_y_mps=1.0, yaw_rate_radps=0.0)
    assert truth.beta_rad == math.atan2(1.0, 10.0) > 0  # sliding left: β > 0
    arrays = SampleArrays.from_samples(
        [VehicleSample(0, 0, 0, 0, 0, 0, 0, 0, truth), VehicleSample(1, 0, 0, 0, 0, 0, 0, 0, truth)]
    )
    assert arrays.beta_rad().tolist() == [truth.beta_rad] * 2


def test_beta_without_truth_is_an_error() -> None:
    z = np.zeros(1)
    with pytest.raises(SampleArraysError, match="no ground truth"):
        SampleArrays(np.arange(1), z, z, z, z, z, z, z).beta_rad()


def test_paper_noise_is_converted_to_si() -> None:
    sigma = SensorNoiseSigma.paper()
    assert sigma.velocity_mps == pytest.approx(1 / 3.6)
    assert sigma.acceleration_mps2 == 0.1
    assert sigma.yaw_rate_radps == pytest.approx(0.2 * math.pi / 180)
    assert sigma.stl_m == 0.001
    assert SensorNoiseSigma.none() == SensorNoiseSigma(0.0, 0.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="stl_m"):
        SensorNoiseSigma(0.1, 0.1, 0.1, -1.0)
