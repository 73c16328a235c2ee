"""Sensor noise: the paper's σ per channel, seeded and reproducible, truth untouched."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import add_noise, exact_samples, noise_profile, run_seed
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import load_vehicle


@pytest.fixture(scope="module")
def exact():
    result = simulate(
        load_vehicle("paper_sedan"), Maneuver("r", "random_steer", 20.0, 70.0, 300.0, seed=2)
    )
    return exact_samples(result)


def test_paper_profile_is_the_papers_sigma():
    sigma = noise_profile("paper")
    assert sigma.velocity_mps == pytest.approx(1.0 / 3.6)
    assert sigma.acceleration_mps2 == pytest.approx(0.1)
    assert sigma.yaw_rate_radps == pytest.approx(math.radians(0.2))
    assert sigma.stl_m == pytest.approx(0.001)
    with pytest.raises(ValueError, match="paper, none"):
        noise_profile("loud")


def test_noise_has_the_configured_standard_deviation_per_channel(exact):
    sigma = SensorNoiseSigma(0.3, 0.2, 0.01, 0.002)
    noisy = add_noise(exact, sigma, 11)
    pairs = [
        ("x_v_mps", 0.3),
        ("y_v_mps", 0.3),
        ("x_a_mps2", 0.2),
        ("y_a_mps2", 0.2),
        ("yaw_rate_radps", 0.01),
        ("stl_m", 0.002),
    ]
    for name, std in pairs:
        err = getattr(noisy, name) - getattr(exact, name)
        assert abs(np.mean(err)) < 4 * std / math.sqrt(len(err)), name
        assert np.std(err) == pytest.approx(std, rel=0.05), name


def test_ground_truth_and_stamps_are_never_noisy(exact):
    noisy = add_noise(exact, noise_profile("paper"), 3)
    np.testing.assert_array_equal(noisy.stamp_ns, exact.stamp_ns)
    np.testing.assert_array_equal(noisy.truth_v_x_mps, exact.truth_v_x_mps)
    np.testing.assert_array_equal(noisy.truth_v_y_mps, exact.truth_v_y_mps)
    np.testing.assert_array_equal(noisy.truth_yaw_rate_radps, exact.truth_yaw_rate_radps)


@settings(max_examples=20, deadline=None)
@given(st.integers(0, 2**31 - 1))
def test_same_seed_gives_the_same_noise_and_another_seed_does_not(seed):
    result = simulate(load_vehicle("paper_sedan"), Maneuver("s", "straight", 0.1, 50.0, 0.0))
    exact = exact_samples(result)
    sigma = noise_profile("paper")
    a = add_noise(exact, sigma, run_seed(seed, "run"))
    b = add_noise(exact, sigma, run_seed(seed, "run"))
    c = add_noise(exact, sigma, run_seed(seed, "other_run"))
    np.testing.assert_array_equal(a.y_v_mps, b.y_v_mps)
    assert not np.array_equal(a.y_v_mps, c.y_v_mps)


def test_none_profile_leaves_the_signals_exact(exact):
    clean = add_noise(exact, noise_profile("none"), 5)
    assert clean == exact


def test_stamps_are_exact_400hz_nanoseconds(exact):
    assert np.all(np.diff(exact.stamp_ns) == 2_500_000)
