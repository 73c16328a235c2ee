"""The vectorised CDR codec produces rosbags' bytes exactly and decodes them back."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_msgs_py import topics
from sideslip_msgs_py.cdr import SampleEncoder, decode_columns, stack_rows
from sideslip_msgs_py.messages import TypestoreMessages, sample_to_messages
from sideslip_msgs_py.sample import GroundTruth, SampleArrays, SensorNoiseSigma, VehicleSample

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)
sigmas = st.builds(SensorNoiseSigma, *[st.floats(0, 10, allow_nan=False, allow_infinity=False)] * 4)
FACTORY = TypestoreMessages()


@st.composite
def sample_lists(draw: st.DrawFn) -> list[VehicleSample]:
    n = draw(st.integers(1, 8))
    stamps = sorted(draw(st.sets(st.integers(0, 2**31 * 10**9 - 1), min_size=n, max_size=n)))
    with_truth = draw(st.booleans())
    return [
        VehicleSample(
            s,
            *(draw(finite) for _ in range(7)),
            truth=GroundTruth(draw(finite), draw(finite), draw(finite)) if with_truth else None,
        )
        for s in stamps
    ]


@settings(max_examples=150, deadline=None)
@given(sample_lists(), sigmas)
def test_vectorised_bytes_equal_rosbags_serialize_cdr(
    samples: list[VehicleSample], sigma: SensorNoiseSigma
) -> None:
    store = FACTORY.typestore
    rows = SampleEncoder(sigma, FACTORY).encode(SampleArrays.from_samples(samples))
    expected_topics = topics.SAMPLE_TOPICS if samples[0].truth else topics.SENSOR_TOPICS
    assert tuple(rows) == expected_topics
    for i, sample in enumerate(samples):
        for topic, msg in sample_to_messages(sample, FACTORY, sigma).items():
            assert rows[topic][i].tobytes() == bytes(store.serialize_cdr(msg, msg.__msgtype__))


@settings(max_examples=50, deadline=None)
@given(sample_lists())
def test_vectorised_decode_returns_the_encoded_columns(samples: list[VehicleSample]) -> None:
    arrays = SampleArrays.from_samples(samples)
    rows = SampleEncoder(SensorNoiseSigma.paper(), FACTORY).encode(arrays)
    raws = [r.tobytes() for r in rows[topics.IMU]]
    imu = decode_columns(topics.IMU, stack_rows(raws))
    assert imu is not None
    np.testing.assert_array_equal(imu["stamp_ns"], arrays.stamp_ns)
    np.testing.assert_array_equal(imu["angular_velocity.z"], arrays.yaw_rate_radps)
    steer = decode_columns(topics.STEERING, rows[topics.STEERING])
    assert steer is not None
    np.testing.assert_array_equal(steer["position[0]"], arrays.stl_m)
    np.testing.assert_array_equal(steer["velocity[0]"], arrays.stl_rate_mps)


def test_decode_declines_a_joint_state_with_other_joints() -> None:
    store = FACTORY.typestore
    msg = FACTORY.JointState(
        header=FACTORY.Header(stamp=FACTORY.Time(sec=1, nanosec=2), frame_id="base_link"),
        name=["steering_rick"],  # same length, other name: must not be taken as ours
        position=np.array([0.1]),
        velocity=np.array([0.2]),
        effort=np.zeros(0),
    )
    raw = bytes(store.serialize_cdr(msg, msg.__msgtype__))
    assert decode_columns(topics.STEERING, stack_rows([raw])) is None


def test_decode_handles_another_frame_id_length() -> None:
    store = FACTORY.typestore
    hdr = FACTORY.Header(stamp=FACTORY.Time(sec=3, nanosec=4), frame_id="imu_link_front")
    msg = FACTORY.TwistStamped(
        header=hdr,
        twist=FACTORY.Twist(
            linear=FACTORY.Vector3(x=1.5, y=-0.5, z=0.0),
            angular=FACTORY.Vector3(x=0.0, y=0.0, z=0.25),
        ),
    )
    raw = bytes(store.serialize_cdr(msg, msg.__msgtype__))
    cols = decode_columns(topics.TWIST, stack_rows([raw, raw]))
    assert cols is not None
    assert cols["stamp_ns"].tolist() == [3_000_000_004] * 2
    assert cols["twist.linear.y"].tolist() == [-0.5, -0.5]
