"""The estimator's health as one diagnostic: level, one-line message, key values.

Pure: the node reports what it sees to a :class:`StatusTracker` (arrivals, frames,
publications; times passed in), which turns it into an :class:`Observation` once per
status period; :func:`assess` makes the diagnostic the node publishes on /sideslip/status.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, fields
from typing import Any, Final

import numpy as np

from sideslip_msgs_py.outputs import DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN
from sideslip_msgs_py.timing import RATE_HZ

from .estimator import Estimator, EstimatorStats

LEVEL_NAMES = {DIAGNOSTIC_OK: "OK", DIAGNOSTIC_WARN: "WARN", DIAGNOSTIC_ERROR: "ERROR"}
LOG_EVERY_S: Final = 5.0
"""Repeated rejections of one kind are logged at most this often [s]."""


@dataclass(frozen=True)
class Counts:
    """The core's counters at one moment; ``now - before`` gives what happened between."""

    rejections: int = 0
    drops: int = 0
    resets: int = 0
    estimates: int = 0
    below_min_speed: int = 0
    no_estimate: int = 0

    @classmethod
    def of(cls, stats: EstimatorStats) -> Counts:
        return cls(
            rejections=sum(stats.rejected.values()),
            drops=stats.dropped,
            resets=sum(stats.resets.values()),
            estimates=stats.estimates,
            below_min_speed=stats.below_min_speed,
            no_estimate=stats.no_estimate,
        )

    def __sub__(self, before: Counts) -> Counts:
        return Counts(
            **{f.name: getattr(self, f.name) - getattr(before, f.name) for f in fields(self)}
        )


@dataclass(frozen=True)
class Observation:
    """What the node saw since the previous status (times in seconds)."""

    input_ages_s: Mapping[str, float | None]
    """Per input topic: seconds since the last message arrived (None: never)."""
    wrong_types: Sequence[str]
    """One line per publisher on an input topic with a type other than the contract's."""
    silence_timeout_s: float
    window_fill: tuple[int, int]
    latencies_s: Sequence[float]
    """Receive-to-publish time of each estimate since the previous status."""
    new: Counts
    """What the counters did since the previous status."""
    publishers: Mapping[str, Sequence[str]] = field(default_factory=dict)
    """Per input topic: the nodes publishing it with the contract's type."""
    wrong_frames: Sequence[str] = ()
    """One line per input topic whose latest message carried another frame than the
    contract's."""
    input_rate_hz: float | None = None
    """Measured IMU rate (None until measured)."""
    expected_rate_hz: float = RATE_HZ
    rate_refused: bool = False
    """The measured rate is not the back-end model's: no estimates (an error)."""
    held: int = 0
    """IMU messages held: a stamp jump waiting for the next message."""
    future_stamps: int = 0
    """IMU messages found stamped ahead of their time line, since start."""
    sigmas_rad: Sequence[float] = ()
    """The published standard deviation of each estimate since the previous status."""
    widened: int = 0
    """Of those, the estimates whose window reached beyond the driving a fine-tuned
    model was fitted on: σ widened, or (``pso_lstm.beyond_fit_range`` start) the start
    model's estimate and σ published. The status key keeps its first name,
    ``sigma_widened``, for the consumers that read it."""
    imu_scale: tuple[Sequence[str], Mapping[str, str]] = ((), {})
    """The Y_a check's warnings and values (:meth:`.imu_scale.ImuScale.report`)."""


@dataclass(frozen=True)
class Status:
    level: int
    message: str
    values: dict[str, str]


def _sigma_values(sigmas_rad: Sequence[float], widened: int) -> dict[str, str]:
    """p50 / p95 of the published σ of β̂ [deg] since the previous status, and the share
    of those estimates whose window reached beyond the model's fitted driving."""
    sig = np.degrees(np.asarray(sigmas_rad, dtype=float))
    if not sig.size:
        return {k: "n/a" for k in ("beta_sigma_deg_p50", "beta_sigma_deg_p95", "sigma_widened")}
    return {
        "beta_sigma_deg_p50": f"{np.percentile(sig, 50):.4f}",
        "beta_sigma_deg_p95": f"{np.percentile(sig, 95):.4f}",
        "sigma_widened": f"{widened / sig.size:.3f}",
    }


def assess(
    obs: Observation,
    stats: EstimatorStats,
    backend: str,
    model_id: str,
    caveats: Sequence[str] = (),
) -> Status:
    """Worst finding first: ERROR (unusable input), WARN (degraded, or a back-end's
    standing ``caveats``), else OK."""
    errors: list[str] = list(obs.wrong_types)
    warnings: list[str] = list(caveats)
    new = obs.new
    for topic, nodes in obs.publishers.items():
        if len(nodes) > 1:
            warnings.append(f"{len(nodes)} publishers on {topic}: {', '.join(nodes)}")
    warnings.extend(obs.wrong_frames)
    rate = obs.input_rate_hz
    if obs.rate_refused and rate is not None:
        errors.append(
            f"IMU at {rate:.1f} Hz, the model expects {obs.expected_rate_hz:g} Hz: no "
            "estimate (resample the input, or use a model trained at this rate)"
        )
    elif rate is not None and abs(rate / obs.expected_rate_hz - 1.0) > 0.1:
        warnings.append(
            f"IMU at {rate:.1f} Hz, expected {obs.expected_rate_hz:g} Hz "
            "(missing steps are counted as dropped)"
        )
    silent = [t for t, age in obs.input_ages_s.items() if age is None]
    if silent:
        warnings.append(f"no message yet on {', '.join(silent)}")
    stale = [
        f"{t} silent for {age:.2f} s"
        for t, age in obs.input_ages_s.items()
        if age is not None and age > obs.silence_timeout_s
    ]
    warnings.extend(stale)
    held, length = obs.window_fill
    if not silent and not stale and held < length:
        warnings.append(f"window filling ({held}/{length})")
    warnings.extend(obs.imu_scale[0])
    if new.rejections:
        warnings.append(f"{new.rejections} input(s) rejected: {stats.last_rejection}")
    if new.drops > 0:  # < 0: late arrivals filled drops counted before
        warnings.append(f"{new.drops} sample(s) dropped (gaps in IMU stamps)")
    if new.resets:
        warnings.append(f"window restarted {new.resets} time(s)")
    if new.below_min_speed and not new.estimates:
        warnings.append("below min_speed_mps: no estimate")
    if new.no_estimate and not new.estimates:
        warnings.append(f"{model_id} gave no estimate for {new.no_estimate} sample(s)")
    if errors:
        level, message = DIAGNOSTIC_ERROR, "; ".join(errors + warnings)
    elif warnings:
        level, message = DIAGNOSTIC_WARN, "; ".join(warnings)
    else:
        level, message = DIAGNOSTIC_OK, "estimating"
    lat = np.asarray(obs.latencies_s, dtype=float) * 1e3
    values = {
        "backend": backend,
        "model_id": model_id,
        "window_fill": f"{held}/{length}",
        **{
            f"input_age_s[{t}]": ("never" if age is None else f"{age:.4f}")
            for t, age in obs.input_ages_s.items()
        },
        "latency_ms_p50": f"{np.percentile(lat, 50):.3f}" if lat.size else "n/a",
        "latency_ms_p99": f"{np.percentile(lat, 99):.3f}" if lat.size else "n/a",
        **_sigma_values(obs.sigmas_rad, obs.widened),
        "estimates": str(stats.estimates),
        "accepted_samples": str(stats.accepted),
        "rejected_samples": str(sum(stats.rejected.values())),
        **{f"rejected[{k}]": str(v) for k, v in sorted(stats.rejected.items())},
        "dropped_samples": str(stats.dropped),
        "held_samples": str(obs.held),
        "future_stamps": str(obs.future_stamps),
        "input_rate_hz": "n/a" if rate is None else f"{rate:.1f}",
        "expected_rate_hz": f"{obs.expected_rate_hz:g}",
        **{f"publishers[{t}]": ", ".join(nodes) or "none" for t, nodes in obs.publishers.items()},
        "below_min_speed": str(stats.below_min_speed),
        "no_estimate": str(stats.no_estimate),
        "window_restarts": str(sum(stats.resets.values())),
        **{f"restarts[{k}]": str(v) for k, v in sorted(stats.resets.items())},
        "last_rejection": stats.last_rejection or "-",
        **obs.imu_scale[1],
    }
    return Status(level, message, values)


def input_publishers(
    endpoints: Iterable[tuple[str, str, Iterable[Any]]],
) -> tuple[dict[str, list[str]], list[str]]:
    """Per input topic the nodes publishing the contract's type, and one line per
    publisher of another type.

    ``endpoints``: per input, its topic, the contract's type name and the publishers'
    endpoint infos (``node_namespace``, ``node_name``, ``topic_type``, as rclpy's
    ``get_publishers_info_by_topic`` gives them)."""
    publishers: dict[str, list[str]] = {}
    wrong = []
    for topic, expected, infos in endpoints:
        nodes = publishers.setdefault(topic, [])
        for info in infos:
            who = f"{info.node_namespace.rstrip('/')}/{info.node_name}"
            if info.node_name == "_NODE_NAME_UNKNOWN_":
                who = "(a node not discovered yet)"
            if info.topic_type == expected:
                nodes.append(who)
            else:
                wrong.append(f"{topic}: {who} publishes {info.topic_type}, expected {expected}")
    return publishers, wrong


class StatusTracker:
    """What the node saw between two status messages, and which findings it has logged.

    The node reports arrivals and publications with the steady time ``now_s``
    (``time.monotonic()``, seconds) and logs what the methods say is new; once per status
    period :meth:`observe` gives the :class:`Observation` and starts the next period.
    """

    def __init__(
        self,
        stats: EstimatorStats,
        input_topics: Iterable[str],
        frame_id: str,
        silence_timeout_s: float,
    ) -> None:
        self.frame_id = frame_id
        """The contract's frame for the IMU and twist ("" = no check)."""
        self.silence_timeout_s = silence_timeout_s
        self.last_rx: dict[str, float | None] = dict.fromkeys(input_topics)
        """Per input topic (as subscribed): steady time of the last arrival (None: never)."""
        self.wrong_frames: dict[str, str] = {}
        """Per input topic whose latest message carried another frame: the line saying so."""
        self._frames_logged: set[str] = set()  # topics whose mismatch was logged (once)
        self._seen = Counts.of(stats)
        self._latencies_s: list[float] = []
        self._sigmas_rad: list[float] = []
        self._widened = 0
        self._last_imu: tuple[int, float] | None = None  # (stamp ns, steady s)
        self._logged: dict[str, float] = {}  # rejection reason -> steady s of its last log
        self._wrong_types_logged: set[str] = set()

    def received(self, topic: str, now_s: float) -> None:
        self.last_rx[topic] = now_s

    def imu_received(self, stamp_ns: int, now_s: float) -> None:
        self._last_imu = (stamp_ns, now_s)

    def published(self, latency_s: float, variance_rad2: float, widened: bool = False) -> None:
        """An estimate went out ``latency_s`` after its message arrived, with this variance
        of β̂ (``widened``: beyond the driving the model was fitted on)."""
        self._latencies_s.append(latency_s)
        self._sigmas_rad.append(math.sqrt(variance_rad2))
        self._widened += widened

    def frame_mismatch(self, topic: str, frame_id: str) -> str | None:
        """Note the frame of ``topic``'s latest message: the status warns while it is
        another than the contract's (the frame is used as is) and stops when the topic
        carries the contract's again. Returns the line to log the first time the topic
        carries a wrong frame (once per topic, so a topic that alternates between two
        publishers does not flood the log); None otherwise."""
        if frame_id == self.frame_id or not self.frame_id:
            if self.wrong_frames:
                self.wrong_frames.pop(topic, None)
            return None
        line = self.wrong_frames.get(topic)
        if line is None or f"frame_id '{frame_id}'," not in line:
            line = (
                f"{topic}: frame_id '{frame_id}', expected '{self.frame_id}' "
                f"(used as if {self.frame_id})"
            )
            self.wrong_frames[topic] = line
        if topic in self._frames_logged:
            return None
        self._frames_logged.add(topic)
        return line

    def rejection_due(self, reason: str, now_s: float) -> bool:
        """Whether a rejection for ``reason`` is to be logged (at most every LOG_EVERY_S)."""
        if now_s - self._logged.get(reason, -1e9) < LOG_EVERY_S:
            return False
        self._logged[reason] = now_s
        return True

    def new_wrong_types(self, lines: Iterable[str]) -> list[str]:
        """The wrong-type lines not reported before (each is logged once)."""
        new = [line for line in dict.fromkeys(lines) if line not in self._wrong_types_logged]
        self._wrong_types_logged.update(new)
        return new

    def stamp_ns(self, ros_now_ns: int, now_s: float, wall_ns: int) -> int:
        """The status stamp: the ROS time; with use_sim_time and no /clock (ROS time 0)
        the newest IMU stamp plus the steady time since it arrived, so the stamps still
        advance; before any IMU message the wall time."""
        if ros_now_ns > 0:
            return ros_now_ns
        if self._last_imu is not None:
            stamp, rx = self._last_imu
            return stamp + round((now_s - rx) * 1e9)
        return wall_ns

    def observe(
        self,
        core: Estimator,
        publishers: Mapping[str, Sequence[str]],
        wrong_types: Sequence[str],
        now_s: float,
    ) -> Observation:
        """What happened since the previous call; starts the next status period."""
        counts = Counts.of(core.stats)
        new, self._seen = counts - self._seen, counts
        obs = Observation(
            input_ages_s={
                t: (None if rx is None else now_s - rx) for t, rx in self.last_rx.items()
            },
            wrong_types=wrong_types,
            silence_timeout_s=self.silence_timeout_s,
            window_fill=core.fill,
            latencies_s=self._latencies_s,
            new=new,
            publishers=publishers,
            wrong_frames=list(self.wrong_frames.values()),
            input_rate_hz=core.input_rate_hz,
            expected_rate_hz=core.expected_rate_hz,
            rate_refused=core.rate_refused,
            held=core.held,
            future_stamps=core.stats.future_stamps,
            sigmas_rad=self._sigmas_rad,
            widened=self._widened,
            imu_scale=((), {}) if core.imu_scale is None else core.imu_scale.report(),
        )
        self._latencies_s, self._sigmas_rad, self._widened = [], [], 0
        return obs
