"""Bags recorded with other topics, types, frames and units, read through a topic map."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from foreign_bag import TOPIC_MAP, make_truth, write_foreign_bag
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py.errors import BagError, MissingTopicError
from sideslip_msgs_py.topic_map import TopicMap, TopicMapError
from sideslip_msgs_py.topic_map_read import read_mapped_bag


def test_a_foreign_bag_reads_back_the_body_frame_values_it_was_made_from(tmp_path: Path) -> None:
    truth = make_truth(300)
    bag = write_foreign_bag(tmp_path / "car", truth)
    mapped = read_mapped_bag(bag, TopicMap.from_dict(TOPIC_MAP))
    s = mapped.samples
    assert np.array_equal(s.stamp_ns, truth.stamp_ns)
    for column, expected in (
        ("x_a_mps2", truth.x_a),
        ("y_a_mps2", truth.y_a),
        ("yaw_rate_radps", truth.r),
        ("x_v_mps", truth.x_v),
        ("y_v_mps", truth.y_v),
    ):
        np.testing.assert_array_equal(getattr(s, column), expected, err_msg=column)
    # Steering-wheel degrees → rack travel; the header-less topic falls back to log time.
    np.testing.assert_allclose(s.stl_m, truth.stl, rtol=1e-12, atol=1e-15)
    assert any("/steering_wheel_deg: no header" in n for n in mapped.notes)
    # The INS's east/north velocity, turned by the car's yaw, is the body velocity again.
    np.testing.assert_allclose(s.truth_v_x_mps, truth.x_v, atol=1e-9)
    np.testing.assert_allclose(s.truth_v_y_mps, truth.y_v, atol=1e-9)
    np.testing.assert_allclose(s.beta_rad(), np.arctan2(truth.y_v, truth.x_v), atol=1e-10)


def test_a_reference_beta_in_degrees_and_a_joint_by_name(tmp_path: Path) -> None:
    truth = make_truth(50)
    bag = write_foreign_bag(tmp_path / "car", truth)
    spec = {
        "channels": {
            **TOPIC_MAP["channels"],
            # the yaw rate from the odometry's twist instead, by a different path
            "yaw_rate_radps": {"topic": "/odom", "field": "twist.twist.angular.z"},
        },
        # a (made-up) β reference: the steering-wheel angle topic, scaled to radians
        "reference": {
            "beta_rad": {"topic": "/steering_wheel_deg", "field": "data", "scale": math.pi / 180}
        },
    }
    s = read_mapped_bag(bag, TopicMap.from_dict(spec)).samples
    expected = np.radians(truth.stl / 0.00021)
    np.testing.assert_allclose(s.beta_rad(), expected, atol=1e-12)
    np.testing.assert_array_equal(s.yaw_rate_radps, truth.r)


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ({"channels": {"x_a_mps2": {"topic": "/imu/data"}}}, "channels.x_a_mps2 needs"),
        ({"channels": {"speed": {"topic": "/odom", "field": "x"}}}, "unknown channel(s) ['speed']"),
        ({"reference": {"v_x_mps": {"topic": "/a", "field": "x"}}}, "v_x_mps and v_y_mps together"),
        ({"clock": "stl_rate"}, "clock 'stl_rate'"),
        ({"extra": 1}, "unknown key(s) ['extra']"),
        ({"channels": {"stl_m": {"topic": "/s", "field": "data", "scale": 0}}}, "non-zero"),
        (
            {"reference": {**TOPIC_MAP["reference"], "position_m": [1.2]}},
            "reference.position_m must be [x, y] in metres from the CG",
        ),
        (
            {"reference": {**TOPIC_MAP["reference"], "position_m": [120.0, 0.0]}},
            "within ±10 m of the CG",
        ),
        (
            {"reference": {**TOPIC_MAP["reference"], "position_m": "12"}},
            "reference.position_m must be [x, y]",
        ),
    ],
)
def test_a_bad_topic_map_is_refused_naming_the_key(change: dict, named: str) -> None:
    spec = {**TOPIC_MAP, **change}
    if "channels" in change:
        spec["channels"] = {**TOPIC_MAP["channels"], **change["channels"]}
    with pytest.raises(TopicMapError) as info:
        TopicMap.from_dict(spec, "car.yaml")
    assert named in str(info.value) and "car.yaml" in str(info.value)


def test_a_topic_map_file_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(TOPIC_MAP))
    loaded = TopicMap.load(path)
    assert loaded == TopicMap.from_dict(TOPIC_MAP, str(path))
    assert loaded.topics == {"/imu/data", "/odom", "/steering_wheel_deg", "/ins/velocity_enu"}


def test_a_missing_topic_or_field_is_an_error_naming_it(tmp_path: Path) -> None:
    bag = write_foreign_bag(tmp_path / "car", make_truth(20))
    spec = {**TOPIC_MAP, "channels": {**TOPIC_MAP["channels"]}}
    spec["channels"]["x_v_mps"] = {"topic": "/wheel_speeds", "field": "data"}
    with pytest.raises(MissingTopicError, match=r"/wheel_speeds"):
        read_mapped_bag(bag, TopicMap.from_dict(spec))
    spec["channels"]["x_v_mps"] = {"topic": "/odom", "field": "twist.linear.x"}
    with pytest.raises(BagError, match=r"/odom: field 'twist.linear.x'"):
        read_mapped_bag(bag, TopicMap.from_dict(spec))


@settings(max_examples=25, deadline=None)
@given(yaw=st.floats(-math.pi, math.pi), v_x=st.floats(1.0, 60.0), v_y=st.floats(-5.0, 5.0))
def test_a_velocity_turned_into_the_world_and_back_is_unchanged(
    tmp_path_factory: pytest.TempPathFactory, yaw: float, v_x: float, v_y: float
) -> None:
    truth = make_truth(3)
    truth = type(truth)(**{**vars(truth), "x_v": np.full(3, v_x), "y_v": np.full(3, v_y)})
    truth = type(truth)(**{**vars(truth), "yaw": np.full(3, yaw)})
    bag = write_foreign_bag(tmp_path_factory.mktemp("b") / "car", truth)
    s = read_mapped_bag(bag, TopicMap.from_dict(TOPIC_MAP)).samples
    np.testing.assert_allclose(s.truth_v_x_mps, v_x, atol=1e-9)
    np.testing.assert_allclose(s.truth_v_y_mps, v_y, atol=1e-9)


def test_the_live_mapper_forms_a_sample_on_each_clock_message_from_the_latest_values() -> None:
    from rosbags.typesys import Stores, get_typestore

    from sideslip_msgs_py.live_inputs import LiveMapper

    ts = get_typestore(Stores.ROS2_JAZZY)
    Float64 = ts.types["std_msgs/msg/Float64"]
    spec = {
        "channels": {
            "x_a_mps2": {"topic": "/ax", "field": "data"},
            "y_a_mps2": {"topic": "/ay", "field": "data"},
            "yaw_rate_radps": {"topic": "/ay", "field": "data", "scale": 0.01},
            "x_v_mps": {"topic": "/v", "field": "data"},
            "stl_m": {"topic": "/wheel", "field": "data", "scale": 0.5},
        }
    }
    mapper = LiveMapper(TopicMap.from_dict(spec))
    assert mapper.clock_topic == "/ay"
    assert mapper.on_message("/ay", Float64(data=2.0), 100) is None  # nothing else yet
    for topic, value, t in (("/ax", 0.1, 110), ("/v", 20.0, 120), ("/wheel", 0.04, 130)):
        assert mapper.on_message(topic, Float64(data=value), t) is None
    twist, steering, imu = mapper.on_message("/ay", Float64(data=3.0), 140)
    assert (twist.stamp_ns, twist.x_v_mps, twist.y_v_mps) == (120, 20.0, 0.0)  # y_v unmapped
    assert (steering.stamp_ns, steering.stl_m) == (130, 0.02)
    assert (imu.stamp_ns, imu.x_a_mps2, imu.y_a_mps2, imu.yaw_rate_radps) == (140, 0.1, 3.0, 0.03)
    with pytest.raises(BagError, match="/v: a mapped field"):
        mapper.on_message("/v", ts.types["std_msgs/msg/String"](data="x"), 150)


@settings(max_examples=25, deadline=None)
@given(x=st.floats(-3.0, 3.0), y=st.floats(-1.0, 1.0), yaw=st.floats(-math.pi, math.pi))
def test_a_reference_measured_off_the_cg_is_moved_to_the_cg(
    tmp_path_factory: pytest.TempPathFactory, x: float, y: float, yaw: float
) -> None:
    """An INS whose velocity is that of a point (x, y) m from the CG: with
    ``position_m`` the reference is the CG's velocity and β again, whatever the yaw."""
    cg = make_truth(200)
    cg = type(cg)(**{**vars(cg), "yaw": cg.yaw + yaw})
    # The point's velocity on a rigid body turning at r: v_P = v_cg + r ẑ × (x, y).
    at_p = type(cg)(**{**vars(cg), "x_v": cg.x_v - cg.r * y, "y_v": cg.y_v + cg.r * x})
    bag = write_foreign_bag(tmp_path_factory.mktemp("b") / "car", at_p)
    spec = {**TOPIC_MAP, "reference": {**TOPIC_MAP["reference"], "position_m": [x, y]}}
    s = read_mapped_bag(bag, TopicMap.from_dict(spec)).samples
    np.testing.assert_allclose(s.truth_v_x_mps, cg.x_v, atol=1e-9)
    np.testing.assert_allclose(s.truth_v_y_mps, cg.y_v, atol=1e-9)
    np.testing.assert_allclose(s.beta_rad(), np.arctan2(cg.y_v, cg.x_v), atol=1e-10)


def test_a_reference_off_the_cg_needs_the_yaw_rate() -> None:
    channels = {k: v for k, v in TOPIC_MAP["channels"].items() if k != "yaw_rate_radps"}
    reference = {**TOPIC_MAP["reference"], "position_m": [1.0, 0.0]}
    with pytest.raises(TopicMapError, match="position_m needs the yaw_rate_radps channel"):
        TopicMap.from_dict({**TOPIC_MAP, "channels": channels, "reference": reference})


def test_the_contract_map_reads_our_own_bags_as_read_bag_does(tmp_path: Path) -> None:
    # The map sideslip-imu-scale writes for our topics: the same samples as without it,
    # and the types the node subscribes with.
    from sideslip_msgs_py import topics
    from sideslip_msgs_py.bag import read_bag
    from sideslip_msgs_py.topic_map import contract_topic_map
    from sideslip_sim.generate import generate
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.presets import VehicleRun
    from sideslip_sim.vehicle import load_vehicle

    drive = Maneuver("sine", "sine_steer", 3.0, 60.0, 0.0, stl_amplitude_m=0.04)
    generate([VehicleRun(load_vehicle("compact_rwd"), drive)], tmp_path, progress=False)
    contract_map = TopicMap.from_dict(contract_topic_map())
    assert contract_map.input_types() == {
        t: topics.TOPIC_TYPES[t] for t in (topics.IMU, topics.TWIST, topics.STEERING)
    }
    ours, mapped = (
        read_bag(tmp_path / "sine").samples,
        read_mapped_bag(tmp_path / "sine", contract_map),
    )
    np.testing.assert_array_equal(mapped.samples.stamp_ns, ours.stamp_ns)
    for name in ("x_v_mps", "y_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m"):
        np.testing.assert_allclose(getattr(mapped.samples, name), getattr(ours, name), atol=1e-12)
    np.testing.assert_allclose(mapped.samples.beta_rad(), ours.beta_rad(), atol=1e-12)
    assert contract_topic_map() is not contract_topic_map()  # a fresh mapping each time
