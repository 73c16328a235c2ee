"""An IMU away from the CG, or reading in the body frame with gravity, as real cars' do."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.bag import read_bag
from sideslip_sim.generate import generate_run
from sideslip_sim.imu_mounting import ImuMounting, ImuMountingError, mounted_accelerations
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import exact_samples
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import GRAVITY_MPS2, load_vehicle

TURN = Maneuver("turn", "sine_steer", 6.0, 80.0, 0.0, stl_amplitude_m=0.05)


@pytest.fixture(scope="module")
def left_turn():
    return simulate(load_vehicle("paper_sedan"), TURN)


def test_the_default_mounting_leaves_the_contract_samples_as_they_were(left_turn):
    ideal = exact_samples(left_turn)
    same = exact_samples(left_turn, imu=ImuMounting())
    for name in ("x_a_mps2", "y_a_mps2", "yaw_rate_radps", "truth_v_y_mps"):
        np.testing.assert_array_equal(getattr(same, name), getattr(ideal, name))


def test_a_body_frame_imu_reads_gravity_through_the_roll_of_a_turn(left_turn):
    level = exact_samples(left_turn)
    body = exact_samples(left_turn, imu=ImuMounting(frame="body"))
    # Turning left the body rolls right (φ > 0): the lateral channel reads more than a_y.
    k = int(np.argmax(level.y_a_mps2))
    assert level.y_a_mps2[k] > 3.0 and left_turn.roll_rad[k] > 0.005
    expected = level.y_a_mps2[k] * math.cos(left_turn.roll_rad[k]) + GRAVITY_MPS2 * math.sin(
        left_turn.roll_rad[k]
    )
    assert body.y_a_mps2[k] == pytest.approx(expected, rel=1e-12)
    assert body.y_a_mps2[k] > 1.02 * level.y_a_mps2[k]
    # Ground truth, stamps and the other channels are the run's own.
    np.testing.assert_array_equal(body.truth_v_y_mps, level.truth_v_y_mps)
    np.testing.assert_array_equal(body.yaw_rate_radps, level.yaw_rate_radps)


def test_a_resting_tilted_imu_reads_the_tilt_of_gravity():
    n = 5
    zeros, t = np.zeros(n), np.arange(n) * 0.0025
    roll, pitch = np.full(n, math.radians(3.0)), np.full(n, math.radians(-2.0))
    ax, ay = mounted_accelerations(ImuMounting(frame="body"), t, zeros, zeros, zeros, roll, pitch)
    np.testing.assert_allclose(ay, GRAVITY_MPS2 * math.sin(math.radians(3.0)))
    # Nose up (θ < 0): gravity pulls the IMU's x axis backwards, it reads forwards.
    np.testing.assert_allclose(ax, GRAVITY_MPS2 * math.sin(math.radians(2.0)))


def test_an_imu_ahead_of_the_cg_reads_the_centripetal_and_yaw_acceleration_terms():
    t = np.arange(400) * 0.0025
    r = 0.2 + 0.5 * t  # yaw acceleration 0.5 rad/s²
    zeros = np.zeros_like(t)
    ax, ay = mounted_accelerations(ImuMounting((1.5, 0.0)), t, zeros, zeros, r, zeros, zeros)
    np.testing.assert_allclose(ay, 0.5 * 1.5, rtol=1e-9)
    np.testing.assert_allclose(ax, -(r**2) * 1.5, rtol=1e-9)
    # Left of the CG: the yaw acceleration pushes it backwards, the turn towards the CG.
    ax, ay = mounted_accelerations(ImuMounting((0.0, 0.4)), t, zeros, zeros, r, zeros, zeros)
    np.testing.assert_allclose(ax, -0.5 * 0.4, rtol=1e-9)
    np.testing.assert_allclose(ay, -(r**2) * 0.4, rtol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-2.0, 2.0),
    y=st.floats(-1.0, 1.0),
    body=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_a_mirrored_drive_reads_mirrored_on_a_mirrored_mounting(x, y, body, seed):
    rng = np.random.default_rng(seed)
    t = np.arange(50) * 0.0025
    ax, ay, r = (rng.normal(0, s, 50) for s in (2.0, 5.0, 0.3))
    roll, pitch = rng.normal(0, 0.05, 50), rng.normal(0, 0.03, 50)
    frame = "body" if body else "level"
    fx, fy = mounted_accelerations(ImuMounting((x, y), frame), t, ax, ay, r, roll, pitch)
    mx, my = mounted_accelerations(ImuMounting((x, -y), frame), t, ax, -ay, -r, -roll, pitch)
    np.testing.assert_allclose(mx, fx, atol=1e-9)
    np.testing.assert_allclose(my, -fy, atol=1e-9)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"frame": "tilted"}, "level, body"),
        ({"position_m": (9.0, 0.0)}, "within ±5 m"),
        ({"position_m": (0.0, math.nan)}, "y = nan"),
    ],
)
def test_an_implausible_mounting_is_refused_naming_what_is_wrong(kwargs, match):
    with pytest.raises(ImuMountingError, match=match):
        ImuMounting(**kwargs)


def test_the_mounting_reads_back_from_its_record_and_refuses_unknown_keys():
    mounting = ImuMounting((0.8, -0.1), "body")
    assert ImuMounting.from_mapping(mounting.to_dict()) == mounting
    with pytest.raises(ImuMountingError, match="unknown key"):
        ImuMounting.from_mapping({"frame": "body", "height_m": 0.3})
    with pytest.raises(ImuMountingError, match="give \\[x, y\\]"):
        ImuMounting.from_mapping({"position_m": "front"})


def test_a_generated_bag_records_its_mounting_and_reads_as_mounted(tmp_path):
    car = load_vehicle("paper_sedan")
    mounting = ImuMounting((1.0, 0.0), "body")
    generate_run(car, TURN, tmp_path / "b", noise="none", seed=0, preset_name="t", imu=mounting)
    generate_run(car, TURN, tmp_path / "l", noise="none", seed=0, preset_name="t")
    body, level = read_bag(tmp_path / "b" / "turn"), read_bag(tmp_path / "l" / "turn")
    assert ImuMounting.from_mapping(body.run_metadata["imu"]) == mounting
    assert ImuMounting.from_mapping(level.run_metadata["imu"]) == ImuMounting()
    result = simulate(car, TURN)
    want = exact_samples(result, imu=mounting)
    np.testing.assert_allclose(body.samples.y_a_mps2, want.y_a_mps2, atol=1e-9)
    assert not np.allclose(body.samples.y_a_mps2, level.samples.y_a_mps2, atol=0.05)
