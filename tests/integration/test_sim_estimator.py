"""Simulator node → estimator node → a third process, over real DDS on loopback."""

from __future__ import annotations

import math
import signal

import numpy as np
import pytest
from geometry_msgs.msg import TwistStamped, TwistWithCovarianceStamped
from ros_support import wait_for
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import Float64

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import stamp_ns
from sideslip_msgs_py.nodes.qos import profile_for

SHORT_RUN = ("-p", "scenario:=sine_steer", "-p", "maneuver.duration_s:=4.0")


def sim_args(*extra: str) -> list[str]:
    return ["--ros-args", *SHORT_RUN, *extra]


SAMPLE_TYPES = {
    topics.IMU: Imu,
    topics.TWIST: TwistStamped,
    topics.STEERING: JointState,
    topics.GROUND_TRUTH_TWIST: TwistStamped,
    topics.GROUND_TRUTH_SIDESLIP: Float64,
}


def subscribe_all(probe) -> dict[str, list]:
    """Subscribe every topic the sim publishes (what wait_for_subscribers waits for)."""
    return {t: probe.subscribe(t, m, profile_for(t)) for t, m in SAMPLE_TYPES.items()}


def truth_by_stamp(inbox) -> dict[int, float]:
    return {stamp_ns(r.msg): math.atan2(r.msg.twist.linear.y, r.msg.twist.linear.x) for r in inbox}


@pytest.mark.parametrize(
    ("backend", "tolerance_deg"),
    [("kinematic", 0.5), ("single_track", 0.5), ("pso_lstm", 0.5)],  # pso_lstm: shipped model
)
def test_sideslip_follows_ground_truth_on_a_noise_free_run(spawn, probe, backend, tolerance_deg):
    estimator = spawn("sideslip-estimator", "--ros-args", "-p", f"backend:={backend}")
    truth = probe.subscribe(
        topics.GROUND_TRUTH_TWIST, TwistStamped, profile_for(topics.GROUND_TRUTH_TWIST)
    )
    beta = probe.subscribe(topics.SIDESLIP, Float64, profile_for(topics.SIDESLIP))
    twist = probe.subscribe(
        topics.SIDESLIP_TWIST, TwistWithCovarianceStamped, profile_for(topics.SIDESLIP_TWIST)
    )
    # Looping, so that every process has matched before the samples we compare:
    # matching on loopback takes seconds and best-effort topics are not replayed.
    sim = spawn("sideslip-sim", *sim_args("-p", "noise:=none", "-p", "loop:=true"))

    def pairs():
        gt = truth_by_stamp(list(truth))
        return [
            (
                math.atan2(r.msg.twist.twist.linear.y, r.msg.twist.twist.linear.x),
                gt[stamp_ns(r.msg)],
            )
            for r in list(twist)
            if stamp_ns(r.msg) in gt
        ]

    wait_for(lambda: len(pairs()) >= 1500, 40, "1500 estimates with their ground truth")
    assert sim.stop()[0] == 0
    matched = pairs()
    est, ref = np.array(matched).T
    error_deg = np.degrees(np.abs(est - ref))
    assert error_deg.max() < tolerance_deg, f"max error {error_deg.max():.3f} deg"
    # The run steers both ways: β really moved, this is not a straight-line pass.
    assert np.degrees(np.ptp(ref)) > 1.0
    # /sideslip carries the β of /sideslip/twist (the two subscriptions of the probe may
    # have matched a few messages apart, so compare values, not positions).
    from_twist = {
        round(math.atan2(r.msg.twist.twist.linear.y, r.msg.twist.twist.linear.x), 12) for r in twist
    }
    published = [round(r.msg.data, 12) for r in beta]
    assert len(published) > 1000
    assert sum(b in from_twist for b in published) >= 0.99 * len(published)
    assert estimator.proc.poll() is None


def test_sim_publishes_one_stamp_per_step_at_400_hz_and_clock(spawn, probe):
    inboxes = subscribe_all(probe)
    imu, gt = inboxes[topics.IMU], inboxes[topics.GROUND_TRUTH_TWIST]
    deep_clock = profile_for(topics.CLOCK)  # a fresh profile: best effort, as published
    deep_clock.depth = 100  # the probe's own queue, so its busy thread loses fewer ticks
    clock = probe.subscribe(topics.CLOCK, Clock, deep_clock)
    sim = spawn(
        "sideslip-sim",
        *sim_args("-p", "publish_clock:=true", "-p", "wait_for_subscribers:=1"),
    )
    assert sim.proc.wait(60) == 0, sim.output()
    # 1600 steps; the in-process probe takes six 400-Hz topics and, on a starved CPU,
    # loses some of the IMU's (history depth): the stamps are what this test checks.
    wait_for(lambda: len(imu) > 1200, 10, "most IMU messages")
    stamps = np.array([stamp_ns(r.msg) for r in imu])
    assert np.all(np.diff(stamps) > 0)
    assert np.median(np.diff(stamps)) == 2_500_000
    # Every step's topics share one stamp.
    assert set(stamps.tolist()) & {stamp_ns(r.msg) for r in gt}
    clock_ns = np.array([r.msg.clock.sec * 10**9 + r.msg.clock.nanosec for r in clock])
    assert clock_ns.size > 1000 and np.all(np.diff(clock_ns) > 0)
    # /clock is best effort (rclpy's time source asks for keep last 1): the probe may
    # miss a tick, but every tick is a step's stamp.
    assert np.all((clock_ns - stamps[0]) % 2_500_000 == 0)


def test_real_time_factor_zero_runs_as_fast_as_possible(spawn, probe):
    imu = subscribe_all(probe)[topics.IMU]
    sim = spawn(
        "sideslip-sim",
        *sim_args(
            "-p", "real_time_factor:=0.0", "-p", "wait_for_subscribers:=1", "-p", "rate_hz:=100.0"
        ),
    )
    assert sim.proc.wait(60) == 0, sim.output()
    wait_for(lambda: len(imu) > 0, 5, "IMU messages")
    first, last = imu[0].recv_ns, imu[-1].recv_ns
    assert (last - first) * 1e-9 < 2.0, "4 s of driving should not take real time"
    steps = np.diff([stamp_ns(r.msg) for r in imu])
    # Best effort as fast as possible: the probe may miss messages, never see a 400 Hz one.
    assert steps.min() == 10_000_000 and np.all(steps % 10_000_000 == 0)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_the_sim_within_2_s_with_exit_0(spawn, probe, sig):
    imu = probe.subscribe(topics.IMU, Imu, profile_for(topics.IMU))
    sim = spawn("sideslip-sim", "--ros-args", "-p", "scenario:=paper-test", "-p", "loop:=true")
    wait_for(lambda: len(imu) > 10, 30, "the sim publishing")
    code, seconds = sim.stop(sig)
    assert code == 0, sim.output()
    assert seconds < 2.0


def test_signal_during_the_pause_between_runs_stops_the_sim_at_once(spawn, probe):
    imu = subscribe_all(probe)[topics.IMU]
    # 0.1-s runs at 1/20 of real time: 2 s of driving, then a 10-s pause between runs. The
    # sim waits for the probe, which must hear 30 of the first run's 40 steps.
    sim = spawn(
        "sideslip-sim",
        "--ros-args",
        "-p",
        "scenario:=straight",
        "-p",
        "maneuver.duration_s:=0.1",
        "-p",
        "loop:=true",
        "-p",
        "real_time_factor:=0.05",
        "-p",
        "wait_for_subscribers:=1",
    )
    wait_for(lambda: len(imu) > 0, 30, "the sim publishing")
    n = len(imu)
    wait_for(lambda: len(imu) >= n + 30, 10, "the end of the first run")
    code, seconds = sim.stop(signal.SIGINT)
    assert code == 0, sim.output()
    assert seconds < 2.0
    assert "Traceback" not in sim.output()


@pytest.mark.parametrize(
    ("args", "named"),
    [
        (("-p", "scenario:=scen9"), "unknown scenario 'scen9'"),
        (("-p", "rate_hz:=300.0"), "rate_hz"),
        (("-p", "vehicle:=/nonexistent.yaml"), "/nonexistent.yaml"),
        (("-p", "noise:=loud"), "unknown noise profile 'loud'"),
        (("-p", "real_time_factor:=-1.0"), "real_time_factor"),
        (("-p", "rate_hz:=fast"), "rate_hz must be a double"),
    ],
)
def test_bad_parameter_exits_2_naming_it(spawn, args, named):
    sim = spawn("sideslip-sim", "--ros-args", *args)
    assert sim.proc.wait(30) == 2
    assert named in sim.output()


def test_watch_reports_the_estimate_against_ground_truth(spawn, probe):
    spawn("sideslip-estimator", "--ros-args", "-p", "backend:=kinematic")
    spawn("sideslip-sim", *sim_args("-p", "noise:=none", "-p", "loop:=true"))
    # The watch's 10 s start when it does: start it once estimates flow, so that a slow
    # start of the other two on a loaded machine does not eat its window.
    beta = probe.subscribe(topics.SIDESLIP, Float64, profile_for(topics.SIDESLIP))
    wait_for(lambda: len(beta) > 0, 60, "estimates from the sim through the estimator")
    watch = spawn("sideslip-watch", "--duration", "10", "--quiet")
    assert watch.proc.wait(60) == 0, watch.output()
    summary = watch.output().strip().splitlines()[-1]
    assert "estimates against ground truth" in summary
    mae = float(summary.split("MAE ")[1].split("°")[0])
    assert int(summary.split()[0]) > 1000 and mae < 0.01  # noise-free kinematic: exact
