"""Bags → aligned runs: the runs the trainer's windows come from.

The pipeline, each step a plain function or frozen dataclass:

1. :func:`~sideslip_training.bag_paths.find_bags` resolves the user's paths to bags
   (rosbag2 directories or bare ``.mcap`` files, or folders holding them, such as the
   output of ``sideslip-generate``); imported here, with :class:`DatasetError`.
2. :func:`load_runs` reads each bag with :func:`sideslip_msgs_py.bag.read_bag` (samples
   aligned on the IMU stamp) into :class:`Run` records and a :class:`DatasetReport`.
   Nothing is dropped silently: bags without ground truth, unreadable or truncated bags,
   gaps in time and non-finite samples each get a line naming the bag.
3. :mod:`.splits` splits them by bag or in time, never by window, so no validation
   window overlaps a training window.
4. :class:`~sideslip_training.normalize.Normalizer` (module :mod:`.normalize`) holds the
   z-score statistics, fitted on the training runs only.
5. :class:`~sideslip_training.windows.WindowIndex` (module :mod:`.windows`) indexes the
   windows over the normalised runs.

:func:`data_digest` fingerprints the runs for provenance.

This module holds step 2 and re-exports step 1 (:mod:`.bag_paths`), but not steps 3-5:
they build on :class:`Run` and :class:`DatasetError` from here, so a re-export would make
an import cycle. Import ``Normalizer`` from ``sideslip_training.normalize`` and ``WindowIndex`` /
``TorchWindows`` from ``sideslip_training.windows``.

Units: features keep the units of :data:`sideslip_msgs_py.features.CHANNELS` (m/s, m/s²,
rad/s, m); β is in radians (β = atan2(v_y, v_x) of the ground truth); stamps are int64
nanoseconds; ``max_gap_s`` is in seconds.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import numpy as np

from sideslip_estimator.accelerometer_scale import estimate_scale
from sideslip_msgs_py.bag import BagContents, read_bag
from sideslip_msgs_py.features import CHANNELS, channel_indices
from sideslip_msgs_py.resample import RateError, to_step
from sideslip_msgs_py.sample import SampleArrays
from sideslip_msgs_py.topic_map import TopicMap
from sideslip_msgs_py.topic_map_read import read_mapped_bag

from .accelerometer_check import check_accelerometer
from .bag_paths import DatasetError, find_bags
from .dataset_report import DatasetReport

BETA: Final = "beta_rad"
"""Name under which the target β [rad] appears in reports and non-finite counts."""

MIN_REFERENCE_SPEED_MPS: Final = 1.0
"""Below this forward speed of the reference [m/s] (standstill, creeping, reversing) β
is no target: atan2(v_y, v_x) of a car at rest is the angle of the reference's noise,
and the estimator node publishes nothing below its ``min_speed_mps`` (default the same
1 m/s). A real recording that starts at rest would otherwise train on angles of ±180°."""


# --- runs and the report ----------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Run:
    """One contiguous stretch of samples from one bag: a whole bag, or one segment of it.

    Attributes:
        name: the bag's directory name or file stem; ``<bag>#<k>`` for the k-th segment of
            a bag split at gaps in time.
        path: the bag it came from.
        samples: aligned samples (units of :class:`~sideslip_msgs_py.sample.SampleArrays`).
        notes: what read_bag and load_runs did not take verbatim (truncation, gaps, NaN).
        truncated: the bag was damaged; ``samples`` are (part of) its readable part.
        run_metadata: the run's parameters from the bag ({} when it has none).
        bag: the bag name that :func:`split_runs` splits on (defaults to ``name``).
        car_source: where this run's car parameters come from
            (:data:`~.inputs.CAR_SOURCES`), over the model's ``--car``; None: the
            model's. ``sideslip-train --rehearse`` runs take their own records.
        recording: for a run cut in time out of a longer one (:func:`cut`: a split in
            time, a fold's block), the whole stretch it was cut from; ``offset`` is where
            this run starts in it. Filters that carry a state from sample to sample (the
            UKF observer, the physics baselines) run over the recording from its start and
            are read at this run's samples, as the node, which ran through the earlier
            samples, would have them; no window reaches before the cut. None: the run is
            the whole stretch.
    """

    name: str
    path: Path
    samples: SampleArrays
    notes: tuple[str, ...] = ()
    truncated: bool = False
    run_metadata: dict[str, Any] = field(default_factory=dict)
    bag: str = ""
    car_source: str | None = None
    recording: SampleArrays | None = None
    offset: int = 0

    def __post_init__(self) -> None:
        if not self.bag:
            object.__setattr__(self, "bag", self.name)

    def __len__(self) -> int:
        return len(self.samples)


def _bag_names(bags: Sequence[Path]) -> list[str]:
    """Directory name or file stem; qualified by the parent folder where two collide."""
    stems = [p.name if p.is_dir() else p.stem for p in bags]
    names = [
        s if stems.count(s) == 1 else f"{p.parent.name}/{s}"
        for p, s in zip(bags, stems, strict=True)
    ]
    return [n if names.count(n) == 1 else str(p) for p, n in zip(bags, names, strict=True)]


def slice_samples(samples: SampleArrays, start: int, stop: int) -> SampleArrays:
    """Rows start:stop of every column."""
    cols = {f.name: getattr(samples, f.name) for f in dataclasses.fields(samples)}
    return SampleArrays(**{k: (None if v is None else v[start:stop]) for k, v in cols.items()})


def cut(run: Run, start: int, stop: int, name: str | None = None) -> Run:
    """Samples ``start:stop`` of ``run`` as a run of its own (named ``name``, default
    the run's), which remembers the recording it was cut from (:attr:`Run.recording`)."""
    return dataclasses.replace(
        run,
        name=run.name if name is None else name,
        samples=slice_samples(run.samples, start, stop),
        recording=run.samples if run.recording is None else run.recording,
        offset=run.offset + start,
    )


def filtered_span(run: Run) -> tuple[SampleArrays, int]:
    """The samples a stateful filter runs over to be read at ``run``'s samples: the
    recording up to the run's end, and where the run's samples start in it."""
    if run.recording is None:
        return run.samples, 0
    stop = run.offset + len(run.samples)
    if not np.array_equal(run.recording.stamp_ns[run.offset : stop], run.samples.stamp_ns):
        raise ValueError(f"{run.name}: its samples are not those of its recording at {run.offset}")
    return slice_samples(run.recording, 0, stop), run.offset


def without_slow_targets(samples: SampleArrays) -> tuple[SampleArrays, int]:
    """``samples`` with the reference velocity set to NaN (so β is NaN: no window's
    target, not scored) where its forward speed is below :data:`MIN_REFERENCE_SPEED_MPS`,
    and how many such samples there were. The sensor channels stay: windows that end at
    speed still read them."""
    if not samples.has_truth:
        return samples, 0
    slow = samples.truth_v_x_mps < MIN_REFERENCE_SPEED_MPS
    count = int(np.count_nonzero(slow))
    if count == 0:
        return samples, 0
    v_x, v_y = samples.truth_v_x_mps.copy(), samples.truth_v_y_mps.copy()
    v_x[slow] = v_y[slow] = np.nan
    return dataclasses.replace(samples, truth_v_x_mps=v_x, truth_v_y_mps=v_y), count


def _nonfinite_counts(samples: SampleArrays, channels: Sequence[str]) -> dict[str, int]:
    counts = {c: int(np.count_nonzero(~np.isfinite(getattr(samples, c)))) for c in channels}
    if samples.has_truth:
        counts[BETA] = int(np.count_nonzero(~np.isfinite(samples.beta_rad())))
    return {c: n for c, n in counts.items() if n}


def _nonfinite_rows(samples: SampleArrays, channels: Sequence[str]) -> int:
    bad = np.zeros(len(samples), dtype=bool)
    for c in channels:
        bad |= ~np.isfinite(getattr(samples, c))
    if samples.has_truth:
        bad |= ~np.isfinite(samples.beta_rad())
    return int(np.count_nonzero(bad))


def _read_mapped(path: Path, topic_map: TopicMap) -> BagContents:
    mapped = read_mapped_bag(path, topic_map)
    notes = (f"read through {topic_map.source}", *mapped.notes)
    return BagContents(path, mapped.samples, {}, {}, mapped.truncated, notes)


def load_runs(
    paths: Sequence[str | Path],
    *,
    require_truth: bool = True,
    max_gap_s: float = 0.01,
    channels: Sequence[str] = CHANNELS,
    on_bag: Callable[[Path], None] | None = None,
    step_s: float | None = None,
    topic_map: TopicMap | None = None,
) -> tuple[list[Run], DatasetReport]:
    """Read every bag under ``paths`` into runs, reporting everything not used verbatim.

    Args:
        paths: bags or folders of bags (see :func:`find_bags`).
        require_truth: refuse (and list) bags without ground truth; training needs β.
            A bag whose ground truth is present but nowhere finite counts as without.
        max_gap_s: consecutive samples further apart than this [s] split the run into
            segments ``<bag>#0``, ``<bag>#1``, ... so that no window spans the gap.
            The default (10 ms = 4 steps at 400 Hz) tolerates a few lost IMU messages.
        channels: channels checked for NaN/inf and reported (default: every model
            channel); β is always checked when present. Windows containing such samples
            are never produced (:meth:`~.windows.WindowIndex.build`).
        on_bag: called with each bag's path before it is read (e.g. a progress bar).
        step_s: the model's step [s]: a bag at another rate is resampled to it (low-pass
            filtered first when downsampling) or, outside 50–1000 Hz, refused naming
            both rates (:func:`sideslip_msgs_py.resample.to_step`); the report says
            which. None: bags are used at whatever rate they have.
        topic_map: read every bag through this map (bags recorded by another stack,
            :mod:`sideslip_msgs_py.topic_map`) instead of the contract's topics.

    Returns:
        The runs in bag order (segments in time order), and the report.

    Raises:
        DatasetError: a path does not exist or holds no bag, or no usable run is left
            (the message lists why each bag was refused).
    """
    if not (max_gap_s > 0.0 and math.isfinite(max_gap_s)):
        msg = f"max_gap_s must be a positive number of seconds, got {max_gap_s!r}"
        raise DatasetError(msg)
    channel_indices(tuple(channels))  # unknown names raise FeatureError
    bags = find_bags(paths)
    names = _bag_names(bags)
    max_gap_ns = round(max_gap_s * 1e9)
    runs: list[Run] = []
    lines: list[str] = []
    refused: list[str] = []
    truncated: list[str] = []
    gaps = nonfinite = 0
    for path, name in zip(bags, names, strict=True):
        if on_bag is not None:
            on_bag(path)
        try:
            contents = read_bag(path) if topic_map is None else _read_mapped(path, topic_map)
        except Exception as err:
            # One damaged bag must not abort the others; the type and message are reported
            # and load_runs raises when nothing usable is left. (read_bag raises BagError
            # for what it recognises, but e.g. a bare MCAP magic lets a TypeError through.)
            refused.append(f"{name}: unreadable ({type(err).__name__}: {err})")
            lines.append(f"{name}: ERROR unreadable, not used: {type(err).__name__}: {err}")
            continue
        samples = contents.samples
        notes = list(contents.notes)
        lines.extend(f"{name}: {note}" for note in contents.notes)
        if contents.truncated:
            truncated.append(name)
            lines.append(f"{name}: truncated bag; its readable part ({len(samples)} samples) used")
        if len(samples) == 0:
            refused.append(f"{name}: no samples")
            lines.append(f"{name}: no samples, not used")
            continue
        truthless = not samples.has_truth or not np.isfinite(samples.beta_rad()).any()
        if truthless and require_truth:
            refused.append(f"{name}: no ground truth")
            lines.append(f"{name}: no ground truth (no β target), refused for training")
            continue
        if truthless:
            lines.append(f"{name}: no ground truth; kept (require_truth=False)")

        if step_s is not None:
            try:
                resampled = to_step(samples, step_s, max_gap_s=max_gap_s)
            except RateError as err:
                refused.append(f"{name}: {err}")
                lines.append(f"{name}: ERROR {err}; not used")
                continue
            samples = resampled.samples
            if resampled.note:
                notes.append(resampled.note)
                lines.append(f"{name}: {resampled.note}")
            if len(samples) == 0:
                refused.append(f"{name}: nothing left after resampling")
                continue

        if counts := _nonfinite_counts(samples, channels):
            rows = _nonfinite_rows(samples, channels)
            nonfinite += rows
            detail = ", ".join(f"{c}: {n}" for c, n in counts.items())
            note = (
                f"{rows} sample(s) with NaN/inf ({detail}); no window contains them"
                if not truthless
                else f"{rows} sample(s) with NaN/inf ({detail})"
            )
            notes.append(note)
            lines.append(f"{name}: {note}")
        samples, slow = without_slow_targets(samples)
        if slow:
            note = (
                f"{slow} sample(s) with the reference's forward speed under "
                f"{MIN_REFERENCE_SPEED_MPS:g} m/s (standstill, creeping, reversing): no β "
                "target there and not scored; windows that end at speed still read them"
            )
            notes.append(note)
            lines.append(f"{name}: {note}")
            if require_truth and not np.isfinite(samples.beta_rad()).any():
                refused.append(
                    f"{name}: reference under {MIN_REFERENCE_SPEED_MPS:g} m/s throughout"
                )
                lines.append(f"{name}: no β target (never at speed), refused for training")
                continue

        onset = contents.run_metadata.get("spin_onset_s")
        if isinstance(onset, int | float) and not isinstance(onset, bool):
            # A run that spun (the simulator flags |β| > 30° at speed) is used up to the
            # spin only: the approach to the limit is what a stability controller needs;
            # the spin itself (|β| of tens of degrees, no longer a steered car) would
            # dominate a squared-error loss. See docs/training.md.
            keep = int(np.searchsorted(samples.stamp_ns - samples.stamp_ns[0], onset * 1e9))
            note = f"spun at {onset:.2f} s: samples after the spin onset left out"
            notes.append(note)
            lines.append(f"{name}: {note}")
            samples = slice_samples(samples, 0, keep)
            if len(samples) == 0:
                refused.append(f"{name}: spun at once")
                continue

        steps = np.diff(samples.stamp_ns)
        cuts = (np.flatnonzero(steps > max_gap_ns) + 1).tolist()
        if cuts:
            gaps += len(cuts)
            t_s = (samples.stamp_ns - samples.stamp_ns[0]) * 1e-9
            where = ", ".join(
                f"{steps[c - 1] * 1e-9:.3f} s after {t_s[c - 1]:.3f} s" for c in cuts[:5]
            )
            more = f" and {len(cuts) - 5} more" if len(cuts) > 5 else ""
            note = (
                f"{len(cuts)} gap(s) in time over {max_gap_s:g} s ({where}{more}); "
                f"split into segments {name}#0..{name}#{len(cuts)}"
            )
            notes.append(note)
            lines.append(f"{name}: {note}")
        bounds = [0, *cuts, len(samples)]
        for k, (start, stop) in enumerate(itertools.pairwise(bounds)):
            runs.append(
                Run(
                    name=f"{name}#{k}" if cuts else name,
                    path=path,
                    samples=slice_samples(samples, start, stop) if cuts else samples,
                    notes=tuple(notes),
                    truncated=contents.truncated,
                    run_metadata=contents.run_metadata,
                    bag=name,
                )
            )
    # Recordings from other stacks most often go wrong in the accelerometer's frame, unit
    # or sign; with a reference that is measurable, so it is said here, for every tool.
    accelerometer = check_accelerometer(runs) if require_truth else None
    if accelerometer is not None and accelerometer.warning:
        lines.append(accelerometer.warning)
    # Without a reference (or with too little of it) the speed and yaw rate still
    # measure Y_a's scale: said the same way, with the topic map's fix.
    accelerometer_scale = estimate_scale(runs, fit_bias=True) if accelerometer is None else None
    if accelerometer_scale is not None and accelerometer_scale.warning:
        lines.append(accelerometer_scale.warning)
    report = DatasetReport(
        bags_found=len(bags),
        bags_used=len({r.bag for r in runs}),
        runs=len(runs),
        samples=sum(len(r) for r in runs),
        duration_s=sum(float(r.samples.stamp_ns[-1] - r.samples.stamp_ns[0]) * 1e-9 for r in runs),
        refused=tuple(refused),
        truncated=tuple(truncated),
        gaps=gaps,
        nonfinite_samples=nonfinite,
        lines=tuple(lines),
        accelerometer=accelerometer,
        accelerometer_scale=accelerometer_scale,
    )
    if not runs:
        reasons = "; ".join(refused)
        msg = f"no usable run in {len(bags)} bag(s): {reasons}"
        raise DatasetError(msg)
    return runs, report


# --- provenance -------------------------------------------------------------------------------


def data_digest(runs: Iterable[Run]) -> str:
    """sha256 (hex) over run names and every sample column, independent of run order.

    Columns are hashed as little-endian bytes in SampleArrays field order, with a marker
    for absent ground truth, so the digest is the same on every platform.
    """
    h = hashlib.sha256(b"sideslip-data-v1\x00")
    for run in sorted(runs, key=lambda r: r.name):
        h.update(run.name.encode() + b"\x00")
        h.update(len(run.samples).to_bytes(8, "little"))
        for f in dataclasses.fields(run.samples):
            col = getattr(run.samples, f.name)
            if col is None:
                h.update(f"{f.name}:none\x00".encode())
            else:
                h.update(f"{f.name}\x00".encode())
                h.update(np.ascontiguousarray(col, dtype=col.dtype.newbyteorder("<")).tobytes())
    return h.hexdigest()


__all__ = [
    "BETA",
    "MIN_REFERENCE_SPEED_MPS",
    "DatasetError",
    "Run",
    "data_digest",
    "find_bags",
    "load_runs",
    "slice_samples",
    "without_slow_targets",
]
