"""Field mapping between samples and ROS messages, for both message back-ends."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py import topics
from sideslip_msgs_py.cdr import decode_columns, stack_rows
from sideslip_msgs_py.errors import MessageFieldError
from sideslip_msgs_py.messages import (
    UNMEASURED_VARIANCE,
    RclpyMessages,
    TypestoreMessages,
    messages_to_sample,
    sample_to_messages,
    steering_fields,
)
from sideslip_msgs_py.sample import GroundTruth, SensorNoiseSigma, VehicleSample

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
stamps = st.integers(0, 2**31 * 10**9 - 1)  # builtin_interfaces/Time.sec is int32
truths = st.none() | st.builds(GroundTruth, finite, finite, finite)
samples = st.builds(
    VehicleSample, stamps, finite, finite, finite, finite, finite, finite, finite, truths
)

RCLPY = RclpyMessages()
TYPESTORE = TypestoreMessages()


@settings(max_examples=200, deadline=None)
@given(samples)
def test_rclpy_messages_round_trip_exactly(sample: VehicleSample) -> None:
    msgs = sample_to_messages(sample, RCLPY, SensorNoiseSigma.paper())
    assert messages_to_sample(msgs) == sample


@settings(max_examples=200, deadline=None)
@given(samples)
def test_typestore_messages_round_trip_exactly_through_cdr(sample: VehicleSample) -> None:
    store = TYPESTORE.typestore
    msgs = sample_to_messages(sample, TYPESTORE, SensorNoiseSigma.paper())
    decoded = {
        t: store.deserialize_cdr(store.serialize_cdr(m, m.__msgtype__), m.__msgtype__)
        for t, m in msgs.items()
    }
    assert messages_to_sample(decoded) == sample


@settings(deadline=None)
@given(samples)
def test_rclpy_serialised_messages_read_back_through_rosbags_and_the_fast_decoder(
    sample: VehicleSample,
) -> None:
    # Byte equality with rclpy is not expected: Fast-CDR leaves padding bytes
    # uninitialised and pads a message's end. The values must survive both readers.
    from rclpy.serialization import deserialize_message, serialize_message

    msgs = sample_to_messages(sample, RCLPY, SensorNoiseSigma.paper())
    raws = {t: serialize_message(m) for t, m in msgs.items()}
    decoded = {t: deserialize_message(r, type(msgs[t])) for t, r in raws.items()}
    assert messages_to_sample(decoded) == sample
    for topic, raw in raws.items():
        columns = decode_columns(topic, stack_rows([raw]))
        assert columns is not None, topic
        if "stamp_ns" in columns:
            assert columns["stamp_ns"].tolist() == [sample.stamp_ns]
    steer = decode_columns(topics.STEERING, stack_rows([raws[topics.STEERING]]))
    assert steer is not None
    assert (steer["position[0]"][0], steer["velocity[0]"][0]) == (sample.stl_m, sample.stl_rate_mps)


def test_steps_share_one_stamp_and_frame_and_truth_topics_only_with_truth() -> None:
    sample = VehicleSample(1_234_567_890_123, 20, 0.5, 0.1, 3, 0.2, 0.01, 0.02)
    msgs = sample_to_messages(sample, TYPESTORE, SensorNoiseSigma.none())
    assert tuple(msgs) == topics.SENSOR_TOPICS
    for msg in msgs.values():
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1234, 567_890_123)
        assert msg.header.frame_id == "base_link"
    truth = GroundTruth(20.0, -1.5, 0.3)
    msgs = sample_to_messages(
        VehicleSample(0, 0, 0, 0, 0, 0, 0, 0, truth), TYPESTORE, SensorNoiseSigma.none()
    )
    assert tuple(msgs) == topics.SAMPLE_TOPICS
    assert msgs[topics.GROUND_TRUTH_SIDESLIP].data == math.atan2(-1.5, 20.0)
    joint = msgs[topics.STEERING]
    assert (joint.name, len(joint.effort)) == (["steering_rack"], 0)


def test_imu_covariances_carry_sigma_squared_and_flag_unused_channels() -> None:
    sigma = SensorNoiseSigma.paper()
    imu = sample_to_messages(VehicleSample(0, 0, 0, 0, 0, 0, 0, 0), RCLPY, sigma)[topics.IMU]
    assert imu.orientation_covariance[0] == -1.0
    assert not np.any(imu.orientation_covariance[1:])
    gyro = np.asarray(imu.angular_velocity_covariance).reshape(3, 3)
    accel = np.asarray(imu.linear_acceleration_covariance).reshape(3, 3)
    np.testing.assert_array_equal(
        gyro, np.diag([UNMEASURED_VARIANCE, UNMEASURED_VARIANCE, sigma.yaw_rate_radps**2])
    )
    var_a = sigma.acceleration_mps2**2
    np.testing.assert_array_equal(accel, np.diag([var_a, var_a, UNMEASURED_VARIANCE]))
    assert (imu.orientation.w, imu.orientation.x) == (1.0, 0.0)


def test_steering_without_the_rack_joint_names_topic_and_joint() -> None:
    joint = RCLPY.JointState(name=["wheel"], position=[0.1], velocity=[], effort=[])
    with pytest.raises(MessageFieldError, match=r"/vehicle/steering.*steering_rack"):
        steering_fields(joint)


def test_steering_without_velocity_reads_rate_as_nan() -> None:
    joint = RCLPY.JointState(name=["x", "steering_rack"], position=[0.0, 0.02])
    fields = steering_fields(joint)
    assert fields.stl_m == 0.02
    assert math.isnan(fields.stl_rate_mps)


def test_missing_sensor_topic_is_named() -> None:
    msgs = sample_to_messages(VehicleSample(0, 0, 0, 0, 0, 0, 0, 0), RCLPY, SensorNoiseSigma.none())
    del msgs[topics.TWIST]
    with pytest.raises(MessageFieldError, match="/vehicle/twist"):
        messages_to_sample(msgs)
