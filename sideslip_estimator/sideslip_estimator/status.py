"""The estimator's health as one diagnostic: level, one-line message, key values.

Pure: the node passes in what it observed (receive ages, wrong-type publishers, the
core's counters and latencies) and publishes the result on /sideslip/status.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields

import numpy as np

from sideslip_msgs_py.outputs import DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN
from sideslip_msgs_py.timing import RATE_HZ

from .estimator import EstimatorStats

LEVEL_NAMES = {DIAGNOSTIC_OK: "OK", DIAGNOSTIC_WARN: "WARN", DIAGNOSTIC_ERROR: "ERROR"}


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
        return Counts(*(getattr(self, f.name) - getattr(before, f.name) for f in fields(self)))


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
    """One line per input topic whose messages carry another frame than the contract's."""
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


@dataclass(frozen=True)
class Status:
    level: int
    message: str
    values: dict[str, str]


def _sigma_values(sigmas_rad: Sequence[float]) -> dict[str, str]:
    """p50 / p95 of the published σ of β̂ [deg] since the previous status."""
    sig = np.degrees(np.asarray(sigmas_rad, dtype=float))
    if not sig.size:
        return {"beta_sigma_deg_p50": "n/a", "beta_sigma_deg_p95": "n/a"}
    return {
        "beta_sigma_deg_p50": f"{np.percentile(sig, 50):.4f}",
        "beta_sigma_deg_p95": f"{np.percentile(sig, 95):.4f}",
    }


def assess(obs: Observation, stats: EstimatorStats, backend: str, model_id: str) -> Status:
    """Worst finding first: ERROR (unusable input), WARN (degraded), else OK."""
    errors: list[str] = list(obs.wrong_types)
    warnings: list[str] = []
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
        **_sigma_values(obs.sigmas_rad),
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
    }
    return Status(level, message, values)
