"""A strapdown IMU's accelerations (body frame, gravity in them) levelled with its
attitude, in bags and live, as the contract's gravity-free horizontal ones."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from foreign_bag import TOPIC_MAP, make_truth, quaternion, write_foreign_bag
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.errors import BagError
from sideslip_msgs_py.imu_frame import level_accelerations, roll_pitch
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError
from sideslip_msgs_py.topic_map_read import read_mapped_bag
from sideslip_sim.imu_mounting import ImuMounting, mounted_accelerations

BODY_MAP = {
    **TOPIC_MAP,
    "imu": {"frame": "body", "attitude": {"topic": "/imu/data", "field": "orientation"}},
}


class _Q:
    def __init__(self, x: float, y: float, z: float, w: float) -> None:
        self.x, self.y, self.z, self.w = x, y, z, w


@settings(max_examples=60, deadline=None)
@given(
    roll=st.floats(-0.6, 0.6),
    pitch=st.floats(-0.6, 0.6),
    yaw=st.floats(-math.pi, math.pi),
)
def test_roll_and_pitch_read_back_from_a_quaternion_whatever_the_yaw(roll, pitch, yaw):
    got = roll_pitch(_Q(*quaternion(roll, pitch, yaw)))
    assert got == pytest.approx((roll, pitch), abs=1e-9)


def test_a_zero_quaternion_is_refused_naming_what_an_imu_without_orientation_sends():
    with pytest.raises(ValueError, match="publishes zeros"):
        roll_pitch(_Q(0.0, 0.0, 0.0, 0.0))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**16))
def test_levelling_undoes_the_simulators_body_frame_imu(seed):
    rng = np.random.default_rng(seed)
    n = 40
    t = np.arange(n) * 0.0025
    a_x, a_y, r = rng.normal(0, 3, n), rng.normal(0, 6, n), rng.normal(0, 0.4, n)
    roll, pitch = rng.normal(0, 0.08, n), rng.normal(0, 0.04, n)
    f_x, f_y = mounted_accelerations(ImuMounting(frame="body"), t, a_x, a_y, r, roll, pitch)
    back_x, back_y = level_accelerations(f_x, f_y, roll, pitch)
    np.testing.assert_allclose(back_x, a_x, atol=1e-12)
    np.testing.assert_allclose(back_y, a_y, atol=1e-12)


def test_a_tilt_no_car_survives_gives_nan_not_a_huge_number():
    a_x, a_y = level_accelerations(1.0, 2.0, math.radians(60.0), 0.0)
    assert math.isnan(a_x) and math.isnan(a_y)


def test_a_bag_from_a_strapdown_imu_reads_back_the_level_accelerations(tmp_path: Path) -> None:
    truth = make_truth(300)
    t = (truth.stamp_ns - truth.stamp_ns[0]) * 1e-9
    # The body leans out of the turn by 6°/g of lateral acceleration, and pitches.
    tilt = (math.radians(6.0) * truth.y_a / 9.80665, 0.02 * np.sin(0.5 * t))
    bag = write_foreign_bag(tmp_path / "car", truth, tilt=tilt)
    raw = read_mapped_bag(bag, TopicMap.from_dict(TOPIC_MAP)).samples
    assert np.max(np.abs(raw.y_a_mps2 - truth.y_a)) > 0.1  # gravity is in what it recorded
    mapped = read_mapped_bag(bag, TopicMap.from_dict(BODY_MAP))
    np.testing.assert_allclose(mapped.samples.y_a_mps2, truth.y_a, atol=1e-9)
    np.testing.assert_allclose(mapped.samples.x_a_mps2, truth.x_a, atol=1e-9)
    np.testing.assert_array_equal(mapped.samples.yaw_rate_radps, truth.r)
    assert any("levelled with the roll and pitch of /imu/data" in n for n in mapped.notes)


def test_an_attitude_field_that_is_no_quaternion_is_an_error_naming_it(tmp_path: Path) -> None:
    bag = write_foreign_bag(tmp_path / "car", make_truth(20))
    attitude = {"topic": "/imu/data", "field": "angular_velocity"}
    spec = {**BODY_MAP, "imu": {"frame": "body", "attitude": attitude}}
    with pytest.raises(BagError, match="'angular_velocity'"):
        read_mapped_bag(bag, TopicMap.from_dict(spec))


def test_the_live_mapper_levels_each_sample_with_the_latest_attitude() -> None:
    from rosbags.typesys import Stores, get_typestore

    from sideslip_msgs_py.live_inputs import LiveMapper

    ts = get_typestore(Stores.ROS2_JAZZY)
    Float64, Quaternion = ts.types["std_msgs/msg/Float64"], ts.types["geometry_msgs/msg/Quaternion"]
    spec = {
        "channels": {
            "x_a_mps2": {"topic": "/ax", "field": "data"},
            "y_a_mps2": {"topic": "/ay", "field": "data"},
            "yaw_rate_radps": {"topic": "/r", "field": "data"},
            "x_v_mps": {"topic": "/v", "field": "data"},
            "stl_m": {"topic": "/wheel", "field": "data"},
        },
        "imu": {"frame": "body", "attitude": {"topic": "/att", "field": "data"}},
    }

    class Attitude:  # a message whose field ``data`` is the quaternion
        def __init__(self, q: object) -> None:
            self.data = q

    mapper = LiveMapper(TopicMap.from_dict(spec))
    for topic, value in (("/ax", -1.0), ("/r", 0.3), ("/v", 20.0), ("/wheel", 0.01)):
        mapper.on_message(topic, Float64(data=value), 10)
    assert mapper.on_message("/ay", Float64(data=5.0), 20) is None  # no attitude yet
    roll, pitch = math.radians(4.0), math.radians(1.0)
    q = Quaternion(**dict(zip("xyzw", quaternion(roll, pitch, 2.0), strict=True)))
    assert mapper.on_message("/att", Attitude(q), 30) is None
    _, _, imu = mapper.on_message("/ay", Float64(data=5.0), 40)
    assert imu.y_a_mps2 == pytest.approx((5.0 - 9.80665 * math.sin(roll)) / math.cos(roll))
    assert imu.x_a_mps2 == pytest.approx((-1.0 + 9.80665 * math.sin(pitch)) / math.cos(pitch))
    assert imu.yaw_rate_radps == 0.3


@pytest.mark.parametrize(
    ("imu", "named"),
    [
        ({"frame": "body"}, "needs imu.attitude"),
        ({"frame": "tilted"}, "imu.frame 'tilted'"),
        ({"frame": "level", "attitude": {"topic": "/a", "field": "q"}}, "only read with"),
        ({"frame": "body", "attitude": {"topic": "/a"}}, "needs 'topic' and 'field'"),
        ({"frame": "body", "attitude": {"topic": "/a", "field": "q", "kind": "x"}}, "'kind'"),
        ({"frame": "body", "height_m": 0.4}, "unknown key"),
        ("body", "must be a mapping"),
    ],
)
def test_a_bad_imu_block_is_refused_naming_the_key(imu: object, named: str) -> None:
    with pytest.raises(TopicMapError, match=named):
        TopicMap.from_dict({**TOPIC_MAP, "imu": imu})


def test_a_live_body_frame_map_needs_the_attitudes_message_type() -> None:
    channels = {
        name: {**src, "type": "sensor_msgs/msg/Imu"}
        for name, src in TOPIC_MAP["channels"].items()
        if src["topic"] == "/imu/data"
    }
    spec = {
        "channels": channels,
        "imu": {"frame": "body", "attitude": {"topic": "/ahrs", "field": "orientation"}},
    }
    with pytest.raises(TopicMapError, match="/ahrs"):
        TopicMap.from_dict(spec).input_types()
    spec["imu"]["attitude"]["type"] = "sensor_msgs/msg/Imu"
    assert TopicMap.from_dict(spec).input_types() == {
        "/imu/data": "sensor_msgs/msg/Imu",
        "/ahrs": "sensor_msgs/msg/Imu",
    }


def test_the_yaw_acceleration_follows_a_ramp_and_starts_afresh_after_a_gap() -> None:
    from sideslip_msgs_py.imu_frame import YawAcceleration

    filt = YawAcceleration()
    step = 2_500_000
    assert filt.update(0, 0.1) == 0.0  # nothing to difference yet
    values = [filt.update(k * step, 0.1 + 0.5 * k * step * 1e-9) for k in range(1, 400)]
    assert values[-1] == pytest.approx(0.5, rel=1e-6)
    assert math.isnan(filt.update(400 * step, math.nan))
    assert filt.update(401 * step, 0.1 + 0.5 * 401 * step * 1e-9) == pytest.approx(0.5, rel=1e-3)
    assert filt.update(10**12, 0.3) == 0.0  # a gap: afresh


@settings(max_examples=40, deadline=None)
@given(x=st.floats(-2.0, 2.0), y=st.floats(-1.0, 1.0), seed=st.integers(0, 2**16))
def test_moving_to_the_cg_undoes_the_simulators_lever_arm(x: float, y: float, seed: int) -> None:
    from sideslip_msgs_py.imu_frame import at_cg

    rng = np.random.default_rng(seed)
    t = np.arange(60) * 0.0025
    a_x, a_y, r = rng.normal(0, 3, 60), rng.normal(0, 6, 60), rng.normal(0, 0.4, 60)
    zeros = np.zeros(60)
    f_x, f_y = mounted_accelerations(ImuMounting((x, y)), t, a_x, a_y, r, zeros, zeros)
    back_x, back_y = at_cg(f_x, f_y, r, np.gradient(r, t), (x, y))
    np.testing.assert_allclose(back_x, a_x, atol=1e-9)
    np.testing.assert_allclose(back_y, a_y, atol=1e-9)


def _ahead_of_the_cg(tmp_path: Path, x: float):
    """A foreign bag whose IMU sits ``x`` m ahead of the CG, and its truth."""
    truth = make_truth(2000)
    t = (truth.stamp_ns - truth.stamp_ns[0]) * 1e-9
    r_dot = np.gradient(truth.r, t)
    moved = dataclasses.replace(truth, y_a=truth.y_a + r_dot * x, x_a=truth.x_a - truth.r**2 * x)
    return write_foreign_bag(tmp_path / "ahead", moved), truth


def test_a_bag_from_an_imu_ahead_of_the_cg_reads_back_the_cg_accelerations(tmp_path: Path) -> None:
    bag, truth = _ahead_of_the_cg(tmp_path, 0.8)
    raw = read_mapped_bag(bag, TopicMap.from_dict(TOPIC_MAP)).samples
    mapped = read_mapped_bag(
        bag, TopicMap.from_dict({**TOPIC_MAP, "imu": {"position_m": [0.8, 0]}})
    )
    err_raw = np.abs(raw.y_a_mps2 - truth.y_a)[50:]
    err = np.abs(mapped.samples.y_a_mps2 - truth.y_a)[50:]
    # The causal ṙ lags by its 20-ms time constant: a few cm/s² left of 0.6 m/s².
    assert err_raw.max() > 0.5 and err.max() < 0.1
    np.testing.assert_allclose(mapped.samples.x_a_mps2, truth.x_a, atol=1e-9)
    assert any("lever arm taken out" in n for n in mapped.notes)


def test_the_live_mapper_moves_each_sample_to_the_cg_as_the_bag_reader_does(
    tmp_path: Path,
) -> None:
    from rosbags.highlevel import AnyReader

    from sideslip_msgs_py.live_inputs import LiveMapper

    bag, _ = _ahead_of_the_cg(tmp_path, 0.8)
    spec = {**BODY_MAP, "imu": {**BODY_MAP["imu"], "position_m": [0.8, -0.1]}}
    offline = read_mapped_bag(bag, TopicMap.from_dict(spec)).samples
    mapper = LiveMapper(TopicMap.from_dict(spec))
    live_x, live_y = [], []
    with AnyReader([bag]) as reader:
        for conn, t, raw in reader.messages():
            out = mapper.on_message(conn.topic, reader.deserialize(raw, conn.msgtype), t)
            if out is not None:
                live_x.append(out[2].x_a_mps2)
                live_y.append(out[2].y_a_mps2)
    # The node makes no sample before every channel has a value (the first IMU message
    # comes before the first odometry); from then on the samples are the bag reader's.
    assert len(live_y) == len(offline.y_a_mps2) - 1
    np.testing.assert_allclose(live_x, offline.x_a_mps2[1:], atol=1e-12)
    np.testing.assert_allclose(live_y, offline.y_a_mps2[1:], atol=1e-12)


def test_an_imu_position_needs_the_yaw_rate() -> None:
    channels = {k: v for k, v in TOPIC_MAP["channels"].items() if k != "yaw_rate_radps"}
    with pytest.raises(TopicMapError, match=r"imu\.position_m needs the yaw_rate_radps"):
        TopicMap.from_dict({"channels": channels, "imu": {"position_m": [0.5, 0.0]}})
    with pytest.raises(TopicMapError, match=r"imu\.position_m \[40"):
        TopicMap.from_dict({**TOPIC_MAP, "imu": {"position_m": [40.0, 0.0]}})
