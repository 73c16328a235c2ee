"""Topic names, types and QoS of the wire contract."""

from __future__ import annotations

import subprocess
import sys

import pytest
from rosbags.rosbag2.metadata import parse_qos

from sideslip_msgs_py import qos, topics
from sideslip_msgs_py.errors import UnknownTopicError


def test_contract_topics_have_the_design_names_and_types() -> None:
    assert topics.TOPIC_TYPES == {
        "/vehicle/imu": "sensor_msgs/msg/Imu",
        "/vehicle/twist": "geometry_msgs/msg/TwistStamped",
        "/vehicle/steering": "sensor_msgs/msg/JointState",
        "/vehicle/ground_truth/twist": "geometry_msgs/msg/TwistStamped",
        "/vehicle/ground_truth/sideslip": "std_msgs/msg/Float64",
        "/sideslip": "std_msgs/msg/Float64",
        "/sideslip/twist": "geometry_msgs/msg/TwistWithCovarianceStamped",
        "/sideslip/status": "diagnostic_msgs/msg/DiagnosticArray",
        "/clock": "rosgraph_msgs/msg/Clock",
    }
    assert topics.SAMPLE_TOPICS == topics.SENSOR_TOPICS + topics.GROUND_TRUTH_TOPICS
    assert (topics.BASE_FRAME, topics.STEERING_JOINT) == ("base_link", "steering_rack")


def test_every_contract_type_exists_in_the_jazzy_typestore() -> None:
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    assert set(topics.TOPIC_TYPES.values()) <= set(store.types)


def test_sensor_topics_use_sensor_data_qos_and_outputs_are_reliable() -> None:
    for topic in topics.SAMPLE_TOPICS:
        assert qos.qos_for(topic) == qos.SENSOR_DATA
    for topic in topics.ESTIMATOR_TOPICS:
        assert qos.qos_for(topic) == qos.RELIABLE
    assert set(qos.TOPIC_QOS) == set(topics.TOPIC_TYPES)
    assert (qos.SENSOR_DATA.reliability, qos.SENSOR_DATA.depth) == ("best_effort", 5)
    assert (qos.RELIABLE.reliability, qos.RELIABLE.depth) == ("reliable", 10)


def test_unknown_topic_qos_names_the_topic() -> None:
    with pytest.raises(UnknownTopicError, match="/vehicle/imu_typo"):
        qos.qos_for("/vehicle/imu_typo")


@pytest.mark.parametrize("topic", sorted(topics.TOPIC_TYPES))
def test_offered_qos_yaml_parses_back_to_the_spec(topic: str) -> None:
    assert parse_qos(qos.offered_qos_profiles_yaml(topic)) == [qos.qos_for(topic).to_rosbags()]


def test_package_imports_without_rclpy_or_rosbags() -> None:
    code = (
        "import sys, sideslip_msgs_py, sideslip_msgs_py.bag, sideslip_msgs_py.messages, "
        "sideslip_msgs_py.qos, sideslip_msgs_py.cdr; "
        "print(sorted(m for m in ('rclpy', 'rosbags', 'sensor_msgs') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
