"""What :func:`~sideslip_training.dataset.load_runs` did with the user's bags: counts for
run folders and model metadata, and one line per event (each naming its bag) for a human.
"""

from __future__ import annotations

from dataclasses import dataclass

from sideslip_estimator.accelerometer_scale import AccelerometerScale

from .accelerometer_check import AccelerometerCheck


@dataclass(frozen=True)
class DatasetReport:
    """What :func:`load_runs` did, for a human (``str(report)``) and as counts.

    Attributes:
        bags_found: bags named by the paths.
        bags_used: bags that gave at least one run.
        runs: runs (bags, or segments of bags split at gaps).
        samples: samples in all runs.
        duration_s: time covered by all runs [s] (sum of each run's last - first stamp).
        refused: ``name: reason`` of every bag that gave no run (no ground truth, unreadable,
            no samples).
        truncated: names of damaged bags whose readable part was used.
        gaps: gaps in time at which runs were split.
        nonfinite_samples: samples with NaN/inf in a checked channel or in β (no window
            contains them).
        lines: one line per event, each naming its bag.
        accelerometer: the recorded Y_a against the reference's lateral acceleration
            (:mod:`.accelerometer_check`; None without a reference or enough cornering).
        accelerometer_scale: Y_a's scale and bias from the speed and yaw rate alone
            (:mod:`.accelerometer_scale`), where ``accelerometer`` is None; None with
            too little cornering.
    """

    bags_found: int
    bags_used: int
    runs: int
    samples: int
    duration_s: float
    refused: tuple[str, ...]
    truncated: tuple[str, ...]
    gaps: int
    nonfinite_samples: int
    lines: tuple[str, ...]
    accelerometer: AccelerometerCheck | None = None
    accelerometer_scale: AccelerometerScale | None = None

    def counts(self) -> dict[str, int | float]:
        """The counts as a JSON-ready dict (for run folders and model metadata)."""
        return {
            "bags_found": self.bags_found,
            "bags_used": self.bags_used,
            "bags_refused": len(self.refused),
            "bags_truncated": len(self.truncated),
            "runs": self.runs,
            "samples": self.samples,
            "duration_s": self.duration_s,
            "gaps": self.gaps,
            "nonfinite_samples": self.nonfinite_samples,
        }

    def __str__(self) -> str:
        head = (
            f"{self.bags_used} of {self.bags_found} bag(s) used: {self.runs} run(s), "
            f"{self.samples} samples ({self.duration_s:.1f} s); {len(self.refused)} refused, "
            f"{len(self.truncated)} truncated, {self.gaps} gap(s), "
            f"{self.nonfinite_samples} non-finite sample(s)"
        )
        return "\n".join([head, *(f"  {line}" for line in self.lines)])
