"""--interpolate's weight arithmetic: θ0 + α (θ − θ0), exact at both ends and linear."""

from __future__ import annotations

import math

import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_training.model import ModelConfig, SideslipNet
from sideslip_training.weight_interpolation import check_alpha, interpolate_toward


def _pair(seed: int) -> tuple[SideslipNet, dict[str, torch.Tensor]]:
    torch.manual_seed(seed)
    start = SideslipNet(ModelConfig("lstm", 5, 4, 1))
    tuned = SideslipNet(ModelConfig("lstm", 5, 4, 1))
    return tuned, {k: v.clone() for k, v in start.state_dict().items()}


@settings(max_examples=25, deadline=None)
@given(alpha=st.floats(min_value=1e-3, max_value=1.0), seed=st.integers(0, 1000))
def test_interpolated_weights_lie_on_the_line_from_the_start_to_the_fine_tuned(alpha, seed):
    tuned, start = _pair(seed)
    before = {k: v.clone() for k, v in tuned.state_dict().items()}
    out = interpolate_toward(tuned, start, alpha)
    assert out is tuned
    for name, t in out.state_dict().items():
        expected = start[name] + alpha * (before[name] - start[name])
        torch.testing.assert_close(t, expected, rtol=0, atol=1e-6)


def test_alpha_one_leaves_the_fine_tuned_weights_bit_for_bit():
    tuned, start = _pair(3)
    before = {k: v.clone() for k, v in tuned.state_dict().items()}
    interpolate_toward(tuned, start, 1.0)
    for name, t in tuned.state_dict().items():
        assert torch.equal(t, before[name]), name


@pytest.mark.parametrize("alpha", [0.0, -0.5, 1.5, math.nan, math.inf])
def test_an_alpha_outside_zero_to_one_is_refused_naming_the_option(alpha):
    with pytest.raises(ValueError, match="--interpolate must be within"):
        check_alpha(alpha)


def test_start_weights_of_another_network_are_refused():
    tuned, _ = _pair(1)
    other = SideslipNet(ModelConfig("lstm", 5, 4, 2)).state_dict()
    with pytest.raises(KeyError, match="differently"):
        interpolate_toward(tuned, other, 0.5)
