"""Model input channels and feature sets: one order shared by estimator and trainer."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sideslip_msgs_py.errors import ContractError
from sideslip_msgs_py.features import (
    CHANNELS,
    FEATURE_SETS,
    FeatureError,
    channel_indices,
    feature_set,
)
from sideslip_msgs_py.sample import SENSOR_CHANNELS, SampleArrays, VehicleSample


def test_channels_are_the_papers_six_inputs_in_window_column_order() -> None:
    assert CHANNELS == ("x_v_mps", "y_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m")


def test_every_channel_is_an_attribute_of_samples_and_sample_arrays() -> None:
    # A feature list selects columns from either record without a second mapping.
    for name in CHANNELS:
        assert name in SENSOR_CHANNELS
        assert name in VehicleSample.__dataclass_fields__
        assert name in SampleArrays.__dataclass_fields__


def test_paper_set_is_all_channels_and_measurable_drops_only_lateral_velocity() -> None:
    assert feature_set("paper") == CHANNELS
    assert feature_set("measurable") == tuple(c for c in CHANNELS if c != "y_v_mps")
    assert set(FEATURE_SETS) == {"paper", "measurable"}


def test_every_feature_set_is_in_channel_order_without_repeats() -> None:
    for name, channels in FEATURE_SETS.items():
        idx = channel_indices(channels)
        assert list(idx) == sorted(set(idx)), name


def test_unknown_feature_set_lists_the_known_ones() -> None:
    with pytest.raises(FeatureError, match=r"'imu_only'.*paper, measurable"):
        feature_set("imu_only")


def test_channel_indices_follow_channels() -> None:
    assert channel_indices(("stl_m", "x_v_mps")) == (5, 0)
    assert channel_indices(list(CHANNELS)) == tuple(range(len(CHANNELS)))
    assert channel_indices(()) == ()


@given(st.lists(st.sampled_from(CHANNELS), max_size=12))
def test_channel_indices_select_the_named_columns(names: list[str]) -> None:
    assert [CHANNELS[i] for i in channel_indices(names)] == names


def test_unknown_channel_is_named_with_the_known_ones() -> None:
    with pytest.raises(FeatureError, match=r"\['beta_rad'\].*x_v_mps, y_v_mps"):
        channel_indices(("x_v_mps", "beta_rad"))


def test_feature_error_is_a_contract_value_error() -> None:
    assert issubclass(FeatureError, ContractError) and issubclass(FeatureError, ValueError)
