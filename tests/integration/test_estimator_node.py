"""The estimator node over real DDS: fed by a test publisher, checked on its outputs.

Each test starts ``sideslip-estimator`` as a child process in its own DDS domain,
publishes contract messages from the test's probe node and reads /sideslip,
/sideslip/twist and /sideslip/status back: bad input must give a log line, a status
diagnostic, no crash and never a NaN on a topic.
"""

from __future__ import annotations

import json
import math
import signal
import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TwistWithCovarianceStamped
from kinematic_drive import kinematic_drive
from ros_support import Probe, wait_for
from std_msgs.msg import Float64, String

from sideslip_estimator.backends import BACKENDS
from sideslip_estimator.online_accelerometer_scale import OnlineAccelerometerScale
from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import RclpyMessages, sample_to_messages
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.sample import SensorNoiseSigma, VehicleSample

START_NS = 1_000_000_000_000
DT_NS = 2_500_000
BETA = 0.05  # rad: the kinematic back-end returns atan2(Y_v, X_v) of what we send


def status_values(msg) -> tuple[int, str, dict[str, str]]:
    s = msg.status[0]
    level = s.level[0] if isinstance(s.level, bytes) else int(s.level)
    return level, s.message, {kv.key: kv.value for kv in s.values}


class Feeder:
    """Publishes contract sensor messages from the probe, one step at a time."""

    def __init__(self, probe) -> None:
        self.msgs = RclpyMessages()
        self.pubs = {
            t: probe.publisher(t, self._type(t), profile_for(t)) for t in topics.SENSOR_TOPICS
        }
        self.sigma = SensorNoiseSigma.paper()
        self.probe = probe

    def _type(self, topic: str):
        return {
            topics.IMU: RclpyMessages().Imu,
            topics.TWIST: RclpyMessages().TwistStamped,
            topics.STEERING: RclpyMessages().JointState,
        }[topic]

    def wait_matched(self) -> None:
        for pub in self.pubs.values():
            self.probe.wait_for_subscribers(pub)

    @staticmethod
    def sample(k: int, stamp_ns: int | None = None, **changes: float) -> VehicleSample:
        u = 20.0
        s = VehicleSample(
            stamp_ns=START_NS + k * DT_NS if stamp_ns is None else stamp_ns,
            x_v_mps=u,
            y_v_mps=u * math.tan(BETA),
            x_a_mps2=0.1,
            y_a_mps2=3.0,
            yaw_rate_radps=0.15,
            stl_m=0.02,
            stl_rate_mps=0.0,
        )
        return replace(s, **changes)

    def send(self, sample: VehicleSample, only: tuple[str, ...] = topics.SENSOR_TOPICS) -> None:
        # Twist and steering first: the estimator aligns on the IMU message.
        msgs = sample_to_messages(sample, self.msgs, self.sigma)
        for topic in (topics.TWIST, topics.STEERING, topics.IMU):
            if topic in only:
                self.pubs[topic].publish(msgs[topic])

    def run(self, first: int, count: int, period_s: float = 0.001, **changes: float) -> int:
        """Send ``count`` steps from step ``first`` on; returns the next step index."""
        for k in range(first, first + count):
            self.send(self.sample(k, **changes))
            time.sleep(period_s)
        return first + count


@dataclass
class Rig:
    child: Any
    feeder: Feeder
    beta: list
    twist: list
    status: list


@pytest.fixture
def estimator(spawn, probe):
    """A running estimator (fast status), plus inboxes of its three outputs."""
    child = spawn(
        "sideslip-estimator",
        "--ros-args",
        "-p",
        "backend:=kinematic",  # exact atan2 of what the feeder sends
        "-p",
        "status_rate_hz:=10.0",
        "-p",
        "silence_timeout_s:=0.3",
        "-p",
        "max_gap_s:=5.0",  # the feeder's pace varies: only stamp jumps restart here
    )
    beta = probe.subscribe(topics.SIDESLIP, Float64, profile_for(topics.SIDESLIP))
    twist = probe.subscribe(
        topics.SIDESLIP_TWIST, TwistWithCovarianceStamped, profile_for(topics.SIDESLIP_TWIST)
    )
    status = probe.subscribe(
        topics.SIDESLIP_STATUS, DiagnosticArray, profile_for(topics.SIDESLIP_STATUS)
    )
    wait_for(lambda: len(status) > 0, 30, "the estimator's first status")
    feeder = matched_feeder(probe, status)
    return Rig(child, feeder, beta, twist, status)


def matched_feeder(probe, status) -> Feeder:
    """A feeder whose publishers the node has seen."""
    feeder = Feeder(probe)
    feeder.wait_matched()
    # The probe's publishers have matched the node's subscriptions, but the node may learn
    # of them later (discovery runs per participant) and drop what comes before: wait
    # until its status names a publisher on each input.
    wait_status(
        status,
        lambda lv, m, v: all(v.get(f"publishers[{t}]", "none") != "none" for t in feeder.pubs),
        20,
        "the node seeing the feeder's publishers",
    )
    return feeder


def wait_status(status, predicate, timeout_s: float, what: str):
    def check():
        for rec in reversed(status[-20:]):
            level, message, values = status_values(rec.msg)
            if predicate(level, message, values):
                return level, message, values
        return None

    return wait_for(check, timeout_s, what)


def assert_outputs_finite(beta, twist) -> None:
    values = [r.msg.data for r in beta]
    assert all(math.isfinite(v) for v in values)
    for r in twist:
        lin = r.msg.twist.twist.linear
        assert math.isfinite(lin.x) and math.isfinite(lin.y)
        assert np.all(np.isfinite(r.msg.twist.covariance))


def test_publishes_nothing_until_the_window_is_full_then_beta(estimator):
    rig = estimator
    child, feeder, beta, twist, status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    k = feeder.run(0, 60)
    time.sleep(0.3)  # let in-flight messages land before asserting an absence
    assert beta == [] and twist == []
    feeder.run(k, 150)
    wait_for(lambda: len(beta) >= 20, 10, "estimates once the window is full")
    assert all(r.msg.data == pytest.approx(BETA, abs=1e-12) for r in beta)
    last = twist[-1].msg
    assert last.header.frame_id == topics.BASE_FRAME
    assert last.twist.twist.linear.y == pytest.approx(20.0 * math.tan(BETA))
    wait_status(status, lambda lv, m, v: v["window_fill"] == "100/100", 5, "window full")
    assert child.proc.poll() is None


@pytest.mark.parametrize(
    ("field", "value", "reason"),
    [
        ("x_v_mps", float("nan"), "non_finite"),
        ("y_v_mps", float("inf"), "non_finite"),
        ("x_a_mps2", float("-inf"), "non_finite"),
        ("y_a_mps2", 1.0e4, "out_of_range"),
        ("yaw_rate_radps", float("nan"), "non_finite"),
        ("stl_m", 7.0, "out_of_range"),
    ],
)
def test_bad_values_are_rejected_logged_and_reported(estimator, field, value, reason):
    rig = estimator
    child, feeder, beta, twist, status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    k = feeder.run(0, 120)
    wait_for(lambda: len(beta) > 0, 10, "estimates before the bad input")
    feeder.run(k, 30, **{field: value})
    # Any status with the count (the newest one may already be OK again) that WARNs.
    wait_status(
        status,
        lambda lv, m, v: int(v.get(f"rejected[{reason}]", 0)) > 0 and lv >= 1 and "rejected" in m,
        10,
        f"a WARN naming the rejection, with the {reason} count",
    )
    assert_outputs_finite(beta, twist)
    assert child.proc.poll() is None
    wait_for(lambda: f"rejected input ({reason}" in child.output(), 5, "a log line")


def test_stamp_going_backwards_restarts_the_window(estimator):
    rig = estimator
    child, feeder, beta, twist, status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    feeder.run(0, 150)
    wait_for(lambda: len(beta) > 0, 10, "estimates")
    # A bag played in a loop: stamps jump back to the start (beyond max_gap_s).
    for k in range(20):
        feeder.send(feeder.sample(k, stamp_ns=START_NS - 10 * 10**9 + k * DT_NS))
        time.sleep(0.001)
    found = wait_status(
        status, lambda lv, m, v: v.get("restarts[stamp_backwards]") == "1", 10, "a restart"
    )
    assert found[2]["window_fill"] in {f"{n}/100" for n in range(0, 21)}
    n_before = len(twist)
    for k in range(20, 130):
        feeder.send(feeder.sample(k, stamp_ns=START_NS - 10 * 10**9 + k * DT_NS))
        time.sleep(0.001)
    wait_for(lambda: len(twist) > n_before, 10, "estimates after the window refilled")
    restamped = [
        r.msg.header.stamp.sec * 10**9 + r.msg.header.stamp.nanosec for r in twist[n_before:]
    ]
    # After the restart the window first has to hold 100 samples of the new run again.
    assert min(restamped) >= START_NS - 10 * 10**9 + 99 * DT_NS
    assert child.proc.poll() is None


def test_silent_topic_turns_status_to_warn_and_output_stops(estimator):
    rig = estimator
    child, feeder, beta, _twist, status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    k = feeder.run(0, 150)
    wait_for(lambda: len(beta) > 0, 10, "estimates")
    # Twist goes silent; IMU and steering keep coming, so samples turn stale.
    for j in range(k, k + 200):
        feeder.send(feeder.sample(j), only=(topics.IMU, topics.STEERING))
        time.sleep(0.002)
    found = wait_status(
        status, lambda lv, m, v: lv == 1 and f"{topics.TWIST} silent" in m, 10, "WARN silent"
    )
    assert int(found[2]["rejected[stale_twist]"]) > 0
    n = len(beta)
    time.sleep(0.3)
    assert len(beta) == n, "no estimate may be published from stale inputs"
    assert child.proc.poll() is None


def test_wrong_message_type_on_an_input_topic_is_an_error(estimator, ros_domain, request):
    rig = estimator
    child, feeder, beta, _twist, status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    # Another participant: one DDS participant cannot hold two types on one topic.
    intruder = Probe(ros_domain.domain_id, name="intruder")
    request.addfinalizer(intruder.close)
    bad = intruder.publisher(topics.IMU, String, 10)
    bad.publish(String(data="not an Imu"))
    found = wait_status(status, lambda lv, m, v: lv == 2, 15, "ERROR status for the wrong type")
    assert topics.IMU in found[1] and "std_msgs/msg/String" in found[1]
    wait_for(lambda: "wrong message type" in child.output(), 5, "a log line")
    # The node keeps working for the publishers of the right type.
    feeder.run(0, 150)
    wait_for(lambda: len(beta) > 0, 10, "estimates despite the wrong publisher")
    assert child.proc.poll() is None


def test_flood_drops_oldest_reports_it_and_keeps_latency_bounded(estimator):
    rig = estimator
    child, feeder, beta, twist, status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    feeder.run(0, 150)
    wait_for(lambda: len(twist) > 0, 10, "estimates")
    # As fast as Python can publish: several times what the node can take in.
    n = 6000
    for k in range(150, 150 + n):
        feeder.send(feeder.sample(k))
    sent_done = time.time_ns()
    last_stamp = START_NS + (150 + n - 1) * DT_NS
    wait_status(
        status, lambda lv, m, v: int(v["dropped_samples"]) > 0, 10, "dropped samples reported"
    )

    # Bounded latency: the node is caught up with the newest data shortly after the
    # flood, instead of working through a backlog of thousands of messages.
    def caught_up():
        return twist and (
            twist[-1].msg.header.stamp.sec * 10**9 + twist[-1].msg.header.stamp.nanosec
            >= last_stamp - 10 * DT_NS
        )

    wait_for(caught_up, 5, "an estimate for (nearly) the last flooded sample")
    # The newest estimate arrives at most a second after the last message was sent
    # (before it, when the node kept up): no backlog of thousands of messages.
    assert twist[-1].recv_ns - sent_done < 1.0e9
    assert_outputs_finite(beta, twist)
    assert child.proc.poll() is None


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_the_estimator_within_2_s_with_exit_0(estimator, sig):
    rig = estimator
    child, feeder, beta, _twist, _status = rig.child, rig.feeder, rig.beta, rig.twist, rig.status
    feeder.run(0, 120)
    wait_for(lambda: len(beta) > 0, 10, "estimates")
    code, seconds = child.stop(sig)
    assert code == 0, child.output()
    assert seconds < 2.0


@pytest.mark.parametrize(
    ("param", "named"),
    [
        ("backend:=magic", "unknown backend 'magic'"),
        ("velocity_sigma_mps:=.nan", "velocity_sigma_mps"),
        ("silence_timeout_s:=0.0", "silence_timeout_s"),
        ("window_steps:=100.0", "window_steps must be a int"),
        ("kinematic.smoothing_steps:=500", "kinematic.smoothing_steps"),
        ("pso_lstm.model_file:=no_such_model", "pso_lstm.model_file"),
        ("imu_scale.mode:=fix", "imu_scale.mode must be one of off, report, apply"),
    ],
)
def test_bad_parameter_exits_2_with_the_parameter_named(spawn, param, named):
    # A back-end's parameters are checked when it is built: select it.
    prefix = param.split(":=")[0].split(".", 1)[0]
    backend = prefix if prefix in BACKENDS else "kinematic"
    child = spawn("sideslip-estimator", "--ros-args", "-p", f"backend:={backend}", "-p", param)
    code = child.proc.wait(30)
    assert code == 2, child.output()
    assert named in child.output()
    assert "Traceback" not in child.output()


def test_status_keeps_coming_with_use_sim_time_and_no_clock(spawn, probe):
    spawn(
        "sideslip-estimator", "--ros-args", "-p", "use_sim_time:=true", "-p", "status_rate_hz:=10.0"
    )
    status = probe.subscribe(
        topics.SIDESLIP_STATUS, DiagnosticArray, profile_for(topics.SIDESLIP_STATUS)
    )
    # Nobody publishes /clock: the status must still report that no input arrives.
    found = wait_for(lambda: len(status) >= 3, 30, "three status messages without /clock")
    assert found
    level, message, _ = status_values(status[-1].msg)
    assert level == 1 and "no message yet" in message
    # ... with stamps that mean something (ROS time stands at 0 without /clock).
    stamps = [r.msg.header.stamp.sec * 10**9 + r.msg.header.stamp.nanosec for r in status]
    assert all(s > 0 for s in stamps) and stamps == sorted(stamps)


def test_one_late_message_costs_only_itself(estimator):
    rig = estimator
    child, feeder, twist, status = rig.child, rig.feeder, rig.twist, rig.status
    # Step 150 is held back and sent 10 ms late, after step 154.
    for k in [*range(0, 150), *range(151, 155), 150, *range(155, 300)]:
        if k == 150:
            # Let the node drain its queue first: on a loaded machine DDS (keep last 5)
            # could otherwise drop the very message this test is about.
            time.sleep(0.05)
        feeder.send(feeder.sample(k))
        time.sleep(0.05 if k == 150 else 0.001)  # ... and again after it, for the same reason
    last = START_NS + 299 * DT_NS
    wait_for(lambda: twist and stamp_of(twist[-1].msg) == last, 10, "the last estimate")

    def accounted(v: dict[str, str]) -> int:
        return sum(int(v[k]) for k in ("accepted_samples", "rejected_samples", "dropped_samples"))

    found = wait_status(status, lambda lv, m, v: accounted(v) == 300, 10, "all 300 accounted")
    values = found[2]
    assert values["rejected[late_stamp]"] == "1" and values["window_restarts"] == "0"
    # No blind spot: every step after the window filled has its estimate, except the
    # late one and any that DDS dropped under this burst (counted as dropped).
    stamps = {stamp_of(r.msg) for r in twist}
    expected = {START_NS + k * DT_NS for k in range(99, 300) if k != 150}
    assert stamps <= expected
    assert len(expected - stamps) <= int(values["dropped_samples"])
    assert child.proc.poll() is None


def stamp_of(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def test_two_publishers_on_an_input_are_named_in_the_status(estimator, ros_domain, request):
    rig = estimator
    second = Probe(ros_domain.domain_id, name="second_imu")
    request.addfinalizer(second.close)
    second.publisher(topics.IMU, RclpyMessages().Imu, profile_for(topics.IMU))
    # (Node names follow the endpoints in discovery: wait for both.)
    found = wait_status(
        rig.status,
        lambda lv, m, v: f"2 publishers on {topics.IMU}" in m and "/second_imu" in m,
        15,
        "two publishers, named",
    )
    assert found[0] == 1 and "/probe" in found[1]
    assert rig.child.proc.poll() is None


def test_an_input_in_another_frame_is_a_warning_and_still_used(estimator):
    rig = estimator
    feeder = rig.feeder
    for k in range(150):
        msgs = sample_to_messages(feeder.sample(k), feeder.msgs, feeder.sigma)
        msgs[topics.IMU].header.frame_id = "map"
        for topic in (topics.TWIST, topics.STEERING, topics.IMU):
            feeder.pubs[topic].publish(msgs[topic])
        time.sleep(0.001)
    found = wait_status(rig.status, lambda lv, m, v: "frame_id 'map'" in m, 10, "frame WARN")
    assert found[0] == 1 and f"{topics.IMU}: frame_id 'map', expected 'base_link'" in found[1]
    wait_for(lambda: len(rig.beta) > 0, 10, "estimates from the IMU in another frame")
    wait_for(lambda: "frame mismatch" in rig.child.output(), 5, "a log line")


LIVE_MAP = {
    "channels": {
        "x_a_mps2": {
            "topic": "/imu/data",
            "field": "linear_acceleration.x",
            "type": "sensor_msgs/msg/Imu",
        },
        "y_a_mps2": {
            "topic": "/imu/data",
            "field": "linear_acceleration.y",
            "type": "sensor_msgs/msg/Imu",
        },
        "yaw_rate_radps": {
            "topic": "/imu/data",
            "field": "angular_velocity.z",
            "type": "sensor_msgs/msg/Imu",
        },
        "x_v_mps": {
            "topic": "/odom",
            "field": "twist.twist.linear.x",
            "type": "nav_msgs/msg/Odometry",
        },
        "y_v_mps": {
            "topic": "/odom",
            "field": "twist.twist.linear.y",
            "type": "nav_msgs/msg/Odometry",
        },
        "stl_m": {
            "topic": "/steering_wheel_deg",
            "field": "data",
            "scale": 0.00021,
            "type": "std_msgs/msg/Float64",
        },
    }
}


def _mapped_publishers(probe) -> dict:
    """Publishers of LIVE_MAP's topics, each matched with the node."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu

    pubs = {
        "/imu/data": probe.publisher("/imu/data", Imu, 10),
        "/odom": probe.publisher("/odom", Odometry, 10),
        "/steering_wheel_deg": probe.publisher("/steering_wheel_deg", Float64, 10),
    }
    for pub in pubs.values():
        probe.wait_for_subscribers(pub)
    return pubs


def _publish_mapped_step(pubs: dict, orientation_w: float = 1.0) -> int:
    """One step of LIVE_MAP's topics as a live stack sends it (X_v 20, Y_v 0.3 m/s, the
    IMU stamped now with that orientation's w); returns the stamp [ns]."""
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import Imu

    stamp = time.time_ns()
    sec, nanosec = divmod(stamp, 10**9)
    odom = Odometry()
    odom.header.stamp.sec, odom.header.stamp.nanosec = sec, nanosec
    odom.twist.twist.linear.x, odom.twist.twist.linear.y = 20.0, 0.3
    pubs["/odom"].publish(odom)
    pubs["/steering_wheel_deg"].publish(Float64(data=30.0))
    imu = Imu()
    imu.header.stamp.sec, imu.header.stamp.nanosec = sec, nanosec
    imu.header.frame_id = "imu_link"
    imu.orientation.w = orientation_w
    imu.linear_acceleration.y, imu.angular_velocity.z = 2.0, 0.1
    pubs["/imu/data"].publish(imu)
    return stamp


def test_inputs_of_another_stack_are_read_through_a_topic_map(spawn, probe, tmp_path):
    import yaml

    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(LIVE_MAP))
    spawn(
        "sideslip-estimator",
        "--ros-args",
        "-p",
        "backend:=kinematic",
        "-p",
        f"topic_map_file:={path}",
        "-p",
        "max_gap_s:=5.0",
        "-p",
        "window_steps:=20",
    )
    twist = probe.subscribe(
        topics.SIDESLIP_TWIST, TwistWithCovarianceStamped, profile_for(topics.SIDESLIP_TWIST)
    )
    pubs = _mapped_publishers(probe)
    # β is the same at every step: DDS does not order messages of different topics, so
    # an IMU message may meet the odometry of the step before or after its own.
    sent = set()
    beta = math.atan2(0.3, 20.0)
    # Sent as a live stack sends, until estimates come back: the node's /sideslip/twist
    # publisher may match the probe later than the probe's publishers matched the node
    # (discovery runs per pair), and estimates published before that are not delivered.
    deadline = time.monotonic() + 20.0
    while len(twist) < 20 and time.monotonic() < deadline:
        sent.add(_publish_mapped_step(pubs))
        time.sleep(0.003)
    wait_for(lambda: len(twist) >= 20, 5, "estimates from the mapped topics")
    for rec in twist:
        assert stamp_of(rec.msg) in sent  # stamped with the IMU message it came from
        lin = rec.msg.twist.twist.linear
        assert lin.x == 20.0 and math.atan(lin.y / lin.x) == pytest.approx(beta, abs=1e-12)


def test_a_strapdown_imu_without_orientation_is_named_and_one_with_it_gives_estimates(
    spawn, probe, tmp_path
):
    """A body-frame map levels with the IMU's own orientation: zeros (no orientation
    estimate) are refused per message naming why, a real orientation gives estimates."""
    import yaml

    spec = {
        **LIVE_MAP,
        "imu": {
            "frame": "body",
            "attitude": {
                "topic": "/imu/data",
                "field": "orientation",
                "type": "sensor_msgs/msg/Imu",
            },
            "position_m": [0.5, 0.0],
        },
    }
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(spec))
    child = spawn(
        "sideslip-estimator", "--ros-args", "-p", "backend:=kinematic",
        "-p", f"topic_map_file:={path}", "-p", "max_gap_s:=5.0", "-p", "window_steps:=20",
    )  # fmt: skip
    twist = probe.subscribe(
        topics.SIDESLIP_TWIST, TwistWithCovarianceStamped, profile_for(topics.SIDESLIP_TWIST)
    )
    pubs = _mapped_publishers(probe)

    def send(orientation_w: float) -> None:
        _publish_mapped_step(pubs, orientation_w)  # 0: x, y, z, w all zero
        time.sleep(0.003)

    deadline = time.monotonic() + 10.0
    while "publishes zeros" not in child.output() and time.monotonic() < deadline:
        send(0.0)
    assert "publishes zeros" in child.output() and not twist  # named, nothing published
    deadline = time.monotonic() + 20.0
    while len(twist) < 20 and time.monotonic() < deadline:
        send(1.0)
    wait_for(lambda: len(twist) >= 20, 5, "estimates once the IMU has an orientation")
    assert_outputs_finite([], twist)


@pytest.mark.parametrize(
    ("change", "named"),
    [
        ("no_types", "needs the message type"),
        ("no_y_v", "does not map ['y_v_mps']"),
        ("bad_type", "nav_msgs/msg/NoSuchType of /odom is not installed"),
    ],
)
def test_an_unusable_topic_map_exits_2_naming_why(spawn, tmp_path, change, named):
    import copy

    import yaml

    spec = copy.deepcopy(LIVE_MAP)
    if change == "no_types":
        for entry in spec["channels"].values():
            entry.pop("type")
    elif change == "no_y_v":
        del spec["channels"]["y_v_mps"]
    else:
        for name in ("x_v_mps", "y_v_mps"):
            spec["channels"][name]["type"] = "nav_msgs/msg/NoSuchType"
    path = tmp_path / "car.yaml"
    path.write_text(yaml.safe_dump(spec))
    child = spawn(
        "sideslip-estimator",
        "--ros-args",
        "-p",
        "backend:=kinematic",
        "-p",
        f"topic_map_file:={path}",
    )
    assert child.proc.wait(30) == 2, child.output()
    assert named in child.output() and "Traceback" not in child.output()


def test_the_y_a_measurement_is_restored_applied_reported_and_kept(spawn, probe, tmp_path):
    # What a car with a body-frame IMU left in its state file on an earlier drive.
    before = OnlineAccelerometerScale()
    for sample in kinematic_drive(200.0, scale=1.12, bias=0.08).samples():
        before.add(*sample)
    before.end_stretch()
    state = tmp_path / "imu_scale.json"
    state.write_text(json.dumps(before.state()))
    child = spawn(
        "sideslip-estimator", "--ros-args",
        "-p", "backend:=kinematic",
        "-p", "status_rate_hz:=10.0",
        "-p", "max_gap_s:=5.0",
        "-p", "imu_scale.mode:=apply",
        "-p", f"imu_scale.state_file:={state}",
    )  # fmt: skip
    status = probe.subscribe(
        topics.SIDESLIP_STATUS, DiagnosticArray, profile_for(topics.SIDESLIP_STATUS)
    )
    _, _, values = wait_status(
        status, lambda lv, m, v: v.get("imu_scale_applied") == "yes", 30, "the restored scale"
    )
    assert float(values["imu_scale"]) == pytest.approx(1.12, abs=0.005)
    assert values["imu_scale_chunks"] == "4" and values["imu_scale_mode"] == "apply"
    assert f"4 chunk(s) restored from {state}" in child.output()
    # A short drive, then the node is stopped: the drive joins the kept measurement.
    feeder = matched_feeder(probe, status)
    feeder.run(0, 1600)
    # (Enough for a chunk: 30 blocks of 50 ms; DDS may drop a few under load.)
    wait_status(status, lambda lv, m, v: int(v["accepted_samples"]) >= 1000, 20, "the drive")
    code, _ = child.stop(signal.SIGINT)
    assert code == 0, child.output()
    assert len(json.loads(state.read_text())["chunks"]) == 5
