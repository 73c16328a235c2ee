"""Starting the nodes as ``ros2 run`` does (their console scripts ``sim_node`` and
``estimator_node``), over real DDS: integer values for doubles, refused parameters, and
the simulator's bounded wait for subscribers."""

from __future__ import annotations

import signal

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticArray
from ros_support import wait_for
from sensor_msgs.msg import Imu

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import stamp_ns
from sideslip_msgs_py.nodes.qos import profile_for


def test_sim_node_with_an_integer_real_time_factor_runs_and_publishes(spawn, probe):
    imu = probe.subscribe(topics.IMU, Imu, profile_for(topics.IMU))
    sim = spawn(
        "sim_node",
        "--ros-args",
        "-p", "real_time_factor:=2",  # an integer, as a launch argument `2` arrives
        "-p", "scenario:=straight",
        "-p", "maneuver.duration_s:=4",  # another double given as an integer
        "-p", "loop:=true",
    )  # fmt: skip
    wait_for(lambda: len(imu) >= 400, 30, "400 IMU messages from the sim")
    code, _ = sim.stop(signal.SIGINT)
    assert code == 0, sim.output()
    assert "real_time_factor 2" in sim.output()
    # Faster than real time: simulated seconds per second received (within one run). Not
    # a speed check (the benchmarks do those): real time would give 1.0, and a loaded CI
    # machine has delivered 1.4 of the 2.0 asked, so the bound only tells 2 from 1.
    stamps = np.array([stamp_ns(r.msg) for r in imu[-300:]])
    recv = np.array([r.recv_ns for r in imu[-300:]])
    keep = np.diff(stamps) == 2_500_000  # drop the jump between looped runs
    rate = np.diff(stamps)[keep].sum() / np.diff(recv)[keep].sum()
    assert rate > 1.2


def test_estimator_node_with_integer_doubles_runs_and_publishes_status(spawn, probe):
    status = probe.subscribe(
        topics.SIDESLIP_STATUS, DiagnosticArray, profile_for(topics.SIDESLIP_STATUS)
    )
    estimator = spawn(
        "estimator_node",
        "--ros-args",
        "-p", "backend:=kinematic",  # its parameters are declared when it is selected
        "-p", "status_rate_hz:=5",
        "-p", "max_gap_s:=1",
        "-p", "kinematic.velocity_sigma_mps:=1",
    )  # fmt: skip
    wait_for(lambda: len(status) >= 2, 30, "two /sideslip/status messages")
    code, _ = estimator.stop(signal.SIGINT)
    assert code == 0, estimator.output()


@pytest.mark.parametrize(
    ("executable", "parameter"),
    [
        ("sim_node", "real_time_factor"),
        ("sim_node", "maneuver.mu"),
        ("estimator_node", "max_gap_s"),
        ("estimator_node", "kinematic.velocity_sigma_mps"),
    ],
)
def test_a_string_for_a_double_exits_2_naming_the_parameter(spawn, executable, parameter):
    # A back-end's parameters are declared when it is selected.
    backend = ["-p", "backend:=kinematic"] if parameter.startswith("kinematic.") else []
    node = spawn(executable, "--ros-args", *backend, "-p", f"{parameter}:=fast")
    assert node.proc.wait(30) == 2, node.output()
    out = node.output()
    assert f"bad parameter: parameter {parameter} must be a double" in out
    assert "'fast' (string)" in out and "Traceback" not in out


def test_sim_gives_up_waiting_for_subscribers_after_its_timeout(spawn, probe):
    # One subscriber on the IMU only: the four other topics still lack theirs.
    imu = probe.subscribe(topics.IMU, Imu, profile_for(topics.IMU))
    sim = spawn(
        "sim_node",
        "--ros-args",
        "-p", "wait_for_subscribers:=1",
        "-p", "wait_for_subscribers_timeout_s:=2",
    )  # fmt: skip
    assert sim.proc.wait(30) == 1, sim.output()
    out = sim.output()
    assert "gave up waiting after 2 s (wait_for_subscribers_timeout_s)" in out
    assert f"{topics.TWIST} has 0" in out and f"{topics.GROUND_TRUTH_SIDESLIP} has 0" in out
    assert "exiting without publishing" in out and "steps published" not in out
    assert imu == []
