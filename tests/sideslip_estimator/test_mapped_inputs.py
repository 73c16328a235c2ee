"""The node's inputs from another stack's topics: a topic map (docs/topic-maps.md) read into
the message class of each topic and a mapper, or refused with the file named."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
import yaml
from foreign_bag import RACK_PER_WHEEL_DEG, TOPIC_MAP
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu
from std_msgs.msg import Float64

from sideslip_estimator.backends import Backend, create_backend
from sideslip_estimator.mapped_inputs import mapped_inputs
from sideslip_msgs_py.messages import ImuFields, TwistFields

T0_NS = 1_700_000_000 * 10**9

# A car whose drivers publish an Imu, an Odometry and a steering-wheel angle in degrees:
# the channels of the foreign bag's topic map.
CHANNELS: dict[str, dict[str, Any]] = TOPIC_MAP["channels"]
TYPES = {
    "/imu/data": "sensor_msgs/msg/Imu",
    "/odom": "nav_msgs/msg/Odometry",
    "/steering_wheel_deg": "std_msgs/msg/Float64",
}


def _typed(channels: dict[str, dict[str, Any]]) -> dict[str, dict[str, Any]]:
    return {name: {**src, "type": TYPES[src["topic"]]} for name, src in channels.items()}


def _write(tmp_path: Path, spec: dict[str, Any]) -> str:
    path = tmp_path / "my_car.yaml"
    path.write_text(yaml.safe_dump(spec), encoding="utf-8")
    return str(path)


def _backend(name: str) -> Backend:
    return create_backend(name, {}, 100)


def _stamped(msg: Any, stamp_ns: int) -> Any:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 10**9)
    return msg


def test_no_topic_map_means_the_contract_topics() -> None:
    assert mapped_inputs("", _backend("kinematic")) is None


def test_a_topic_map_gives_each_topic_its_message_class_and_a_mapper_forming_samples(
    tmp_path: Path,
) -> None:
    path = _write(tmp_path, {"channels": _typed(CHANNELS)})
    mapped = mapped_inputs(path, _backend("kinematic"))
    assert mapped is not None
    mapper, classes = mapped
    assert classes == {
        "/imu/data": (Imu, "sensor_msgs/msg/Imu"),
        "/odom": (Odometry, "nav_msgs/msg/Odometry"),
        "/steering_wheel_deg": (Float64, "std_msgs/msg/Float64"),
    }
    # Messages of those very classes, as the subscriptions would deliver them.
    odom = _stamped(Odometry(), T0_NS)
    odom.twist.twist.linear.x, odom.twist.twist.linear.y = 20.0, 0.5
    imu = _stamped(Imu(), T0_NS + 2_500_000)
    imu.linear_acceleration.x, imu.linear_acceleration.y = 0.1, 2.0
    imu.angular_velocity.z = 0.3
    assert mapper.on_message("/odom", odom, T0_NS + 1) is None
    assert mapper.on_message("/steering_wheel_deg", Float64(data=90.0), T0_NS + 2) is None
    out = mapper.on_message("/imu/data", imu, T0_NS + 3)
    assert out is not None
    twist, steering, imu_fields = out
    assert twist == TwistFields(T0_NS, 20.0, 0.5)
    assert steering.stamp_ns == T0_NS + 2  # header-less: its receive time
    assert steering.stl_m == pytest.approx(90.0 * RACK_PER_WHEEL_DEG)
    assert imu_fields == ImuFields(T0_NS + 2_500_000, 0.1, 2.0, 0.3)


def test_the_heading_topic_of_a_world_frame_velocity_is_subscribed_too(tmp_path: Path) -> None:
    channels = _typed(CHANNELS) | {
        "heading": {
            "topic": "/pose",
            "field": "pose.orientation",
            "kind": "quaternion",
            "type": "geometry_msgs/msg/PoseStamped",
        }
    }
    mapped = mapped_inputs(_write(tmp_path, {"channels": channels}), _backend("kinematic"))
    assert mapped is not None
    assert mapped[1]["/pose"] == (PoseStamped, "geometry_msgs/msg/PoseStamped")


def test_a_channel_the_backend_reads_but_the_map_leaves_out_is_refused_naming_it(
    tmp_path: Path,
) -> None:
    without_y_v = {k: v for k, v in _typed(CHANNELS).items() if k != "y_v_mps"}
    path = _write(tmp_path, {"channels": without_y_v})
    kinematic = _backend("kinematic")  # atan2(Y_v, X_v): reads y_v_mps
    with pytest.raises(ValueError) as info:
        mapped_inputs(path, kinematic)
    assert str(info.value) == (
        f"topic_map_file: {path} does not map ['y_v_mps'], which {kinematic.model_id} reads"
    )
    # The single-track observer never reads Y_v: the same map serves it.
    assert mapped_inputs(path, _backend("single_track")) is not None


def test_every_missing_channel_is_named(tmp_path: Path) -> None:
    only_imu = {k: v for k, v in _typed(CHANNELS).items() if k.endswith(("a_mps2", "radps"))}
    path = _write(tmp_path, {"channels": only_imu})
    with pytest.raises(ValueError, match=r"does not map \['stl_m', 'x_v_mps'\], which single"):
        mapped_inputs(path, _backend("single_track"))


def test_a_map_without_message_types_is_refused_naming_the_file_and_topics(
    tmp_path: Path,
) -> None:
    path = _write(tmp_path, {"channels": CHANNELS})  # fine for a bag, not for live topics
    with pytest.raises(ValueError) as info:
        mapped_inputs(path, _backend("kinematic"))
    message = str(info.value)
    assert message.startswith(f"topic_map_file: {path}: live input needs the message type")
    assert "'/imu/data', '/odom', '/steering_wheel_deg'" in message


def test_two_message_types_for_one_topic_are_refused(tmp_path: Path) -> None:
    channels = _typed(CHANNELS)
    channels["y_v_mps"] = {**channels["y_v_mps"], "type": "geometry_msgs/msg/TwistStamped"}
    path = _write(tmp_path, {"channels": channels})
    with pytest.raises(ValueError, match=r"two message types given for \['/odom'\]"):
        mapped_inputs(path, _backend("kinematic"))


def test_an_unreadable_topic_map_is_refused_naming_the_file(tmp_path: Path) -> None:
    path = str(tmp_path / "no_such_map.yaml")
    with pytest.raises(ValueError, match=f"^{re.escape(f'topic_map_file: {path}: cannot read')}"):
        mapped_inputs(path, _backend("kinematic"))


@pytest.mark.parametrize(
    "type_name",
    ["sideslip_no_such_msgs/msg/Speed", "std_msgs/msg/NoSuchType", "std_msgs/Float64", "Float64"],
)
def test_a_message_type_that_is_not_installed_is_refused_naming_it(
    tmp_path: Path, type_name: str
) -> None:
    channels = _typed(CHANNELS)
    channels["stl_m"] = {**channels["stl_m"], "type": type_name}
    path = _write(tmp_path, {"channels": channels})
    with pytest.raises(ValueError) as info:
        mapped_inputs(path, _backend("kinematic"))
    assert str(info.value) == (
        f"topic_map_file: message type {type_name} of /steering_wheel_deg is not installed"
    )


@pytest.mark.parametrize(
    "type_name",
    ["/msg/Float64", "..foo/msg/Float64", "std_msgs/msg/__name__", "std_msgs/msg/_float64"],
)
def test_a_message_type_without_a_package_or_class_is_refused_naming_it(
    tmp_path: Path, type_name: str
) -> None:
    channels = _typed(CHANNELS)
    channels["stl_m"] = {**channels["stl_m"], "type": type_name}
    path = _write(tmp_path, {"channels": channels})
    with pytest.raises(
        ValueError, match=f"message type {re.escape(type_name)} of /steering_wheel_deg"
    ):
        mapped_inputs(path, _backend("kinematic"))
