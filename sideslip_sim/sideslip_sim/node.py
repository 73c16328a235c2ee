"""The simulator node: publishes the contract's sensor and ground-truth topics at 400 Hz.

Plumbing only: :mod:`sideslip_sim.stream` produces each run's samples and CDR bytes;
this node publishes them on an absolute schedule from its own thread (step k is due
at start + k·dt / real_time_factor, so lateness never accumulates into drift) while
the executor keeps serving parameters and discovery on the main thread.
``ros2 run sideslip_sim sim_node`` and the pip console script ``sideslip-sim`` are
this module's ``main``.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from collections import deque
from collections.abc import Sequence

import numpy as np
import rclpy.node

from sideslip_msgs_py import topics
from sideslip_msgs_py.messages import RclpyMessages
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.nodes.ros_parameters import declare
from sideslip_msgs_py.nodes.runtime import StopFlag, run, wants_help
from sideslip_msgs_py.outputs import clock_message
from sideslip_msgs_py.parameter_spec import ParameterSpec, help_text
from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_msgs_py.timing import RATE_HZ
from sideslip_sim.maneuvers import ManeuverError
from sideslip_sim.sensors import noise_profile
from sideslip_sim.stream import ManeuverSpec, SampleStream, select_runs
from sideslip_sim.tir_file import TirError
from sideslip_sim.vehicle import VehicleFileError, load_vehicle

NODE_NAME = "sideslip_sim"
STEP_HZ = round(RATE_HZ)
_SLEEP_GRANULARITY_S = 0.0002  # wake this early and spin the rest: sleep() overshoots
_LONG_WAIT_S = 0.005
_LATENESS_KEPT = 240_000  # last 10 min at 400 Hz: bounded memory when looping for days

PARAMETERS = (
    ParameterSpec(
        "scenario",
        "scen1",
        "What to drive: a Table 4 scenario (scen1..scen4), a preset (paper-test, "
        "paper-train, randomized) run by run, or a manoeuvre family (sine_steer, "
        "double_lane_change, sweep_steer, cornering, random_steer, step_steer, straight) "
        "set by the maneuver.* parameters.",
    ),
    ParameterSpec("vehicle", "paper_sedan", "Shipped vehicle name or vehicle YAML path."),
    ParameterSpec("noise", "paper", "Sensor noise profile: paper or none."),
    ParameterSpec("sigma.velocity_mps", -1.0, "σ of X_v, Y_v [m/s]; < 0 = from the profile."),
    ParameterSpec("sigma.acceleration_mps2", -1.0, "σ of X_a, Y_a [m/s²]; < 0 = profile."),
    ParameterSpec("sigma.yaw_rate_radps", -1.0, "σ of the yaw rate [rad/s]; < 0 = profile."),
    ParameterSpec("sigma.stl_m", -1.0, "σ of the steering rack travel [m]; < 0 = profile."),
    ParameterSpec("seed", 0, "Noise (and randomized preset) seed; same seed, same data."),
    ParameterSpec("randomized_count", 10, "Runs of the randomized preset."),
    ParameterSpec(
        "rate_hz", RATE_HZ, "Publish rate [Hz]: 400 or a divisor (every k-th 2.5-ms step)."
    ),
    ParameterSpec(
        "real_time_factor",
        1.0,
        "Simulated seconds per wall second: 1.0 = real time, 0 = as fast as possible.",
    ),
    ParameterSpec(
        "publish_clock",
        False,
        "Publish /clock with the simulated time (for use_sim_time consumers).",
    ),
    ParameterSpec("loop", False, "Start over after the last run instead of stopping."),
    ParameterSpec("ground_truth", True, "Also publish the ground-truth topics."),
    ParameterSpec(
        "wait_for_subscribers",
        0,
        "Hold the start until every published topic has this many subscribers (0 = start "
        "now). With only an estimator listening, set ground_truth false or it waits on.",
    ),
    ParameterSpec(
        "wait_for_subscribers_timeout_s",
        0.0,
        "Longest wait for those subscribers [s]; when it passes, the node logs which "
        "topics lack them and exits 1 without publishing (0 = wait without limit).",
    ),
    ParameterSpec("maneuver.duration_s", 20.0, "Family runs: duration [s]."),
    ParameterSpec("maneuver.speed_kmh", 80.0, "Family runs: initial speed [km/h]."),
    ParameterSpec("maneuver.torque_nm", 0.0, "Family runs: total drive torque [N m]."),
    ParameterSpec(
        "maneuver.stl_amplitude_m", 0.0, "Family runs: steering amplitude [m]; 0 = automatic."
    ),
    ParameterSpec("maneuver.mu", 1.0, "Family runs: road friction coefficient."),
)


class ParameterError(ValueError):
    """A parameter value the node cannot run with (message names the parameter)."""


def _sigma(values: dict) -> SensorNoiseSigma:
    base = noise_profile(values["noise"])
    picked = {}
    for field in ("velocity_mps", "acceleration_mps2", "yaw_rate_radps", "stl_m"):
        v = values[f"sigma.{field}"]
        picked[field] = getattr(base, field) if v < 0.0 else v
    return SensorNoiseSigma(**picked)


def _decimation(rate_hz: float) -> int:
    k = round(STEP_HZ / rate_hz) if rate_hz > 0 else 0
    if k < 1 or abs(STEP_HZ / k - rate_hz) > 1e-9:
        raise ParameterError(f"rate_hz must be {STEP_HZ} or {STEP_HZ}/k, got {rate_hz}")
    return k


class SimNode(rclpy.node.Node):
    def __init__(self, flag: StopFlag) -> None:
        super().__init__(NODE_NAME)
        self._flag = flag
        try:
            v = declare(self, PARAMETERS)
            rtf = float(v["real_time_factor"])
            if not rtf >= 0.0:
                raise ParameterError(f"real_time_factor must be >= 0, got {rtf}")
            spec = ManeuverSpec(
                **{k.split(".", 1)[1]: float(x) for k, x in v.items() if k.startswith("maneuver.")}
            )
            runs = select_runs(
                v["scenario"], seed=v["seed"], count=v["randomized_count"], spec=spec
            )
            vehicle = load_vehicle(v["vehicle"])
            sigma = _sigma(v)
            decimation = _decimation(v["rate_hz"])
            wait_timeout_s = v["wait_for_subscribers_timeout_s"]
            if not (math.isfinite(wait_timeout_s) and wait_timeout_s >= 0.0):
                raise ParameterError(
                    f"wait_for_subscribers_timeout_s must be finite and >= 0, got {wait_timeout_s}"
                )
        except (ParameterError, ManeuverError, VehicleFileError, TirError, ValueError) as err:
            self.get_logger().fatal(f"bad parameter: {err}")
            raise SystemExit(2) from None
        self.rtf = rtf
        self.stream = SampleStream(
            vehicle,
            runs,
            sigma,
            seed=v["seed"],
            loop=v["loop"],
            decimation=decimation,
            ground_truth=v["ground_truth"],
        )
        wanted = topics.SAMPLE_TOPICS if v["ground_truth"] else topics.SENSOR_TOPICS
        msgs = RclpyMessages()
        self.msg_types = {
            topics.IMU: msgs.Imu,
            topics.TWIST: msgs.TwistStamped,
            topics.STEERING: msgs.JointState,
            topics.GROUND_TRUTH_TWIST: msgs.TwistStamped,
            topics.GROUND_TRUTH_SIDESLIP: msgs.Float64,
        }
        self.pubs = {t: self.create_publisher(self.msg_types[t], t, profile_for(t)) for t in wanted}
        self.clock_pub = None
        if v["publish_clock"]:
            self.clock_pub = self.create_publisher(
                msgs.Clock, topics.CLOCK, profile_for(topics.CLOCK)
            )
        self._msgs = msgs
        self.wait_for_subscribers = int(v["wait_for_subscribers"])
        self.wait_timeout_s = wait_timeout_s
        self.steps_published = 0
        self.lateness_s: deque[float] = deque(maxlen=_LATENESS_KEPT)
        """Publish time − due time of recent real-time steps [s] (logged at the end)."""
        self.get_logger().info(
            f"{v['scenario']} on {vehicle.name}: {len(runs)} run(s), noise {v['noise']}, "
            f"{STEP_HZ / decimation:g} Hz, real_time_factor {rtf:g}"
            + (", looping" if v["loop"] else "")
        )
        self._thread = threading.Thread(target=self._publish_loop, name="sim-publisher")
        self._thread.start()

    def _publish_loop(self) -> None:
        try:
            if not self._wait_for_subscribers():
                self._flag.set("error")
                return
            self._publish_runs()
        except Exception as err:  # a crash here must still stop the process cleanly
            self.get_logger().fatal(f"publisher thread failed: {err!r}")
            self._flag.set("error")
            raise
        late = np.array(self.lateness_s or [0.0]) * 1e3
        self.get_logger().info(
            f"{self.steps_published} steps published; lateness p50/p99/max "
            f"{np.percentile(late, 50):.3f}/{np.percentile(late, 99):.3f}/{late.max():.3f} ms"
        )
        self._flag.set("finished")

    def _wait_for_subscribers(self) -> bool:
        """Hold until every publisher has ``wait_for_subscribers`` subscribers.

        True when they are there (or a stop was requested meanwhile); False, after a
        log line naming the topics that lack them, when the timeout passed first.
        """
        n = self.wait_for_subscribers
        if not n:
            return True
        limit = self.wait_timeout_s
        self.get_logger().info(
            f"waiting for {n} subscriber(s) on each of "
            f"{', '.join(p.topic_name for p in self.pubs.values())}"
            + (f" (at most {limit:g} s)" if limit > 0.0 else "")
        )
        deadline = time.monotonic() + limit
        while not self._flag.is_set():
            counts = {p.topic_name: p.get_subscription_count() for p in self.pubs.values()}
            missing = {t: c for t, c in counts.items() if c < n}
            if not missing:
                break
            if limit > 0.0 and time.monotonic() > deadline:
                lacking = ", ".join(f"{t} has {c}" for t, c in missing.items())
                self.get_logger().fatal(
                    f"gave up waiting after {limit:g} s (wait_for_subscribers_timeout_s): "
                    f"{lacking} subscriber(s), {n} wanted (wait_for_subscribers); "
                    "exiting without publishing"
                )
                return False
            self._flag.wait(0.05)
        return True

    def _publish_runs(self) -> None:
        start_wall = origin_ns = None
        order = [t for t in topics.SAMPLE_TOPICS if t in self.pubs]
        for chunk in self.stream:
            rows = [(self.pubs[t].publish, chunk.messages[t]) for t in order]
            stamps = chunk.samples.stamp_ns.tolist()
            if start_wall is None:
                # The stream stamped its first sample with the wall clock when the run
                # was ready: schedule it at that wall time, on the monotonic clock, so
                # that at real time every message leaves at its stamp.
                origin_ns = stamps[0]
                start_wall = (origin_ns + time.monotonic_ns() - time.time_ns()) * 1e-9
            self.get_logger().info(f"run {chunk.maneuver.name}: {len(stamps)} steps")
            for i, stamp in enumerate(stamps):
                if self._flag.is_set():
                    return
                if self.rtf > 0.0:
                    due = start_wall + (stamp - origin_ns) * 1e-9 / self.rtf
                    if not self._sleep_until(due):
                        return
                if self.clock_pub is not None:
                    self.clock_pub.publish(clock_message(self._msgs, stamp))
                for publish, messages in rows:
                    publish(messages[i].tobytes())
                self.steps_published += 1

    def _sleep_until(self, due: float) -> bool:
        """Wait until ``due`` (monotonic s); False when a stop was requested meanwhile."""
        now = time.monotonic()
        wait = due - now - _SLEEP_GRANULARITY_S
        if wait > _LONG_WAIT_S:
            # Long waits (the pause between runs, slow real-time factors) watch the
            # stop flag; Event.wait is less punctual, so it stops short of the step.
            if self._flag.wait(wait - _LONG_WAIT_S):
                return False
            wait = due - time.monotonic() - _SLEEP_GRANULARITY_S
        if wait > 0.0:
            # clock_nanosleep on the monotonic clock: wakes within tens of µs.
            time.sleep(wait)
        while (now := time.monotonic()) < due:
            pass
        self.lateness_s.append(now - due)
        return not self._flag.is_set()

    def close(self) -> None:
        self._flag.set()
        self._thread.join(timeout=2.0)


def main(argv: Sequence[str] | None = None) -> int:
    args = list(sys.argv if argv is None else argv)
    if wants_help(args):
        print(
            help_text(
                "sideslip-sim (ros2 run sideslip_sim sim_node): full-vehicle simulator "
                "publishing noisy sensor topics and ground truth.",
                [("Parameters", PARAMETERS)],
            )
        )
        return 0
    return run(SimNode, args)


if __name__ == "__main__":
    sys.exit(main())
