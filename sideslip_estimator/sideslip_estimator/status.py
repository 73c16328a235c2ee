"""The estimator's health as one diagnostic: level, one-line message, key values.

Pure: the node passes in what it observed (receive ages, wrong-type publishers, the
core's counters and latencies) and publishes the result on /sideslip/status.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from sideslip_msgs_py.outputs import DIAGNOSTIC_ERROR, DIAGNOSTIC_OK, DIAGNOSTIC_WARN

from .estimator import EstimatorStats

LEVEL_NAMES = {DIAGNOSTIC_OK: "OK", DIAGNOSTIC_WARN: "WARN", DIAGNOSTIC_ERROR: "ERROR"}


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
    new_rejections: int
    new_drops: int
    new_resets: int
    new_estimates: int
    new_below_min_speed: int
    new_no_estimate: int = 0


@dataclass(frozen=True)
class Status:
    level: int
    message: str
    values: dict[str, str]


def assess(obs: Observation, stats: EstimatorStats, backend: str, model_id: str) -> Status:
    """Worst finding first: ERROR (unusable input), WARN (degraded), else OK."""
    errors: list[str] = list(obs.wrong_types)
    warnings: list[str] = []
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
    if obs.new_rejections:
        warnings.append(f"{obs.new_rejections} input(s) rejected: {stats.last_rejection}")
    if obs.new_drops:
        warnings.append(f"{obs.new_drops} sample(s) dropped (gaps in IMU stamps)")
    if obs.new_resets:
        warnings.append(f"window restarted {obs.new_resets} time(s)")
    if obs.new_below_min_speed and not obs.new_estimates:
        warnings.append("below min_speed_mps: no estimate")
    if obs.new_no_estimate and not obs.new_estimates:
        warnings.append(f"{model_id} gave no estimate for {obs.new_no_estimate} sample(s)")
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
        "estimates": str(stats.estimates),
        "accepted_samples": str(stats.accepted),
        "rejected_samples": str(sum(stats.rejected.values())),
        **{f"rejected[{k}]": str(v) for k, v in sorted(stats.rejected.items())},
        "dropped_samples": str(stats.dropped),
        "below_min_speed": str(stats.below_min_speed),
        "no_estimate": str(stats.no_estimate),
        "window_restarts": str(sum(stats.resets.values())),
        **{f"restarts[{k}]": str(v) for k, v in sorted(stats.resets.items())},
        "last_rejection": stats.last_rejection or "-",
    }
    return Status(level, message, values)
