"""Bags → aligned runs → train/validation split → z-score → windows the trainer indexes.

The pipeline, each step a plain function or frozen dataclass:

1. :func:`find_bags` resolves the user's paths to bags (rosbag2 directories or bare
   ``.mcap`` files, or folders holding them, such as the output of ``sideslip-generate``).
2. :func:`load_runs` reads each bag with :func:`sideslip_msgs_py.bag.read_bag` (samples
   aligned on the IMU stamp) into :class:`Run` records and a :class:`DatasetReport`.
   Nothing is dropped silently: bags without ground truth, unreadable or truncated bags,
   gaps in time and non-finite samples each get a line naming the bag.
3. :func:`split_runs` splits by bag, never by window, so no window of a validation bag
   overlaps a training window.
4. :class:`Normalizer` holds the z-score statistics, fitted on the training runs only.
5. :class:`WindowIndex` holds the normalised samples of all runs back to back, plus the
   index of the last sample of every valid window; a batch gathers its windows from that
   (``ends[i] - T + 1 .. ends[i]``), so the windows themselves are never materialised
   (428 k samples × 100 steps × 6 features would be 1 GB; the samples are 10 MB).

Units: features keep the units of :data:`sideslip_msgs_py.features.CHANNELS` (m/s, m/s²,
rad/s, m) before normalisation; β is in radians (β = atan2(v_y, v_x) of the ground truth);
stamps are int64 nanoseconds; ``max_gap_s`` is in seconds.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import numpy.typing as npt

from sideslip_msgs_py.bag import read_bag
from sideslip_msgs_py.features import CHANNELS, channel_indices
from sideslip_msgs_py.sample import SampleArrays

if TYPE_CHECKING:
    import torch

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

STD_FLOOR: Final = 1e-9
"""A channel whose standard deviation is at most this (in its own unit) is constant in
the training data: it gets std 1.0 (so it is only centred) and a note in the normalizer."""

BETA: Final = "beta_rad"
"""Name under which the target β [rad] appears in reports and non-finite counts."""


class DatasetError(ValueError):
    """Bags that cannot make a dataset; the message names the path, bag or setting at fault."""


# --- finding bags ---------------------------------------------------------------------------


def _is_bag_dir(path: Path) -> bool:
    return path.is_dir() and (path / "metadata.yaml").is_file()


def _bags_in(path: Path) -> list[Path]:
    """Bags at ``path``: itself, or its .mcap files, or the bags one level below it."""
    if path.is_file() and path.name == "metadata.yaml":
        path = path.parent
    if path.is_file():
        return [path] if path.suffix == ".mcap" else []
    if _is_bag_dir(path):
        return [path]
    # A directory of bare .mcap files (or a bag directory whose metadata.yaml was lost:
    # read_bag reads each .mcap alone, and the run metadata is inside the .mcap too).
    found = sorted(path.glob("*.mcap"))
    for child in sorted(path.iterdir()):
        if _is_bag_dir(child):
            found.append(child)
        elif child.is_dir():
            found.extend(sorted(child.glob("*.mcap")))
    return found


def find_bags(paths: Sequence[str | Path]) -> list[Path]:
    """Resolve user paths to the bags they name, sorted and without duplicates.

    Each path is a rosbag2 directory (holding metadata.yaml), a bare ``.mcap`` file, a
    directory of bare ``.mcap`` files, or a folder holding such bags one level down (e.g.
    a ``sideslip-generate`` output with its index.json, which is ignored).

    Raises:
        DatasetError: a path does not exist or holds no bag (the message names it).
    """
    if isinstance(paths, str | Path):
        paths = [paths]
    bags: set[Path] = set()
    for raw in paths:
        path = Path(raw)
        if not path.exists():
            msg = f"{path}: no such file or directory (expected a bag or a folder of bags)"
            raise DatasetError(msg)
        found = _bags_in(path)
        if not found:
            msg = (
                f"{path}: holds no bag (expected a rosbag2 directory with metadata.yaml, "
                "an .mcap file, or a folder of them)"
            )
            raise DatasetError(msg)
        bags.update(p.resolve() for p in found)
    return sorted(bags)


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
    """

    name: str
    path: Path
    samples: SampleArrays
    notes: tuple[str, ...] = ()
    truncated: bool = False
    run_metadata: dict[str, Any] = field(default_factory=dict)
    bag: str = ""

    def __post_init__(self) -> None:
        if not self.bag:
            object.__setattr__(self, "bag", self.name)

    def __len__(self) -> int:
        return len(self.samples)


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


def _bag_names(bags: Sequence[Path]) -> list[str]:
    """Directory name or file stem; qualified by the parent folder where two collide."""
    stems = [p.name if p.is_dir() else p.stem for p in bags]
    names = [
        s if stems.count(s) == 1 else f"{p.parent.name}/{s}"
        for p, s in zip(bags, stems, strict=True)
    ]
    return [n if names.count(n) == 1 else str(p) for p, n in zip(bags, names, strict=True)]


def _slice(samples: SampleArrays, start: int, stop: int) -> SampleArrays:
    cols = {f.name: getattr(samples, f.name) for f in dataclasses.fields(samples)}
    return SampleArrays(**{k: (None if v is None else v[start:stop]) for k, v in cols.items()})


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


def load_runs(
    paths: Sequence[str | Path],
    *,
    require_truth: bool = True,
    max_gap_s: float = 0.01,
    channels: Sequence[str] = CHANNELS,
    on_bag: Callable[[Path], None] | None = None,
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
            are never produced (:meth:`WindowIndex.build`).
        on_bag: called with each bag's path before it is read (e.g. a progress bar).

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
            contents = read_bag(path)
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
                    samples=_slice(samples, start, stop) if cuts else samples,
                    notes=tuple(notes),
                    truncated=contents.truncated,
                    run_metadata=contents.run_metadata,
                    bag=name,
                )
            )
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
    )
    if not runs:
        reasons = "; ".join(refused)
        msg = f"no usable run in {len(bags)} bag(s): {reasons}"
        raise DatasetError(msg)
    return runs, report


# --- splitting ------------------------------------------------------------------------------


def _split_key(seed: int, bag: str) -> str:
    # A hash rank, not a shuffled list: deterministic across numpy versions and input
    # order, and adding a bag moves no other bag across the split unless the count changes.
    return hashlib.sha256(f"{seed}\x00{bag}".encode()).hexdigest()


def split_runs(runs: Sequence[Run], val_fraction: float, seed: int) -> tuple[list[Run], list[Run]]:
    """Split runs into (training, validation) by bag: all segments of a bag on one side.

    ``round(val_fraction × bags)`` bags (at least 1, at most bags − 1) go to validation,
    chosen by a seeded hash of the bag name; each side keeps the input order of runs.

    Raises:
        DatasetError: ``val_fraction`` outside [0, 1), no runs, or one bag with
            ``val_fraction`` > 0 (its windows would be on both sides).
    """
    if not 0.0 <= val_fraction < 1.0:
        msg = f"val_fraction must be in [0, 1), got {val_fraction!r}"
        raise DatasetError(msg)
    if not runs:
        raise DatasetError("split_runs: no runs to split")
    if val_fraction == 0.0:
        return list(runs), []
    bags = sorted({r.bag for r in runs})
    if len(bags) < 2:
        msg = (
            f"cannot split 1 bag ({bags[0]}) into training and validation: windows of one "
            "bag on both sides would leak; give more bags or val_fraction=0"
        )
        raise DatasetError(msg)
    n_val = min(max(round(val_fraction * len(bags)), 1), len(bags) - 1)
    val_bags = set(sorted(bags, key=lambda b: _split_key(seed, b))[:n_val])
    return [r for r in runs if r.bag not in val_bags], [r for r in runs if r.bag in val_bags]


# --- z-score ----------------------------------------------------------------------------------


def _feature_matrix(samples: SampleArrays, features: Sequence[str]) -> FloatArray:
    """(S, F) float64 of ``features`` in the given order (units of CHANNELS)."""
    return np.column_stack([np.asarray(getattr(samples, c), np.float64) for c in features])


@dataclass(frozen=True, eq=False)
class Normalizer:
    """Z-score statistics: z = (x − mean) / std per feature, and likewise for β.

    Attributes:
        features: channel names, in model input order.
        mean: per-feature mean, in the channel's unit (float64, read-only).
        std: per-feature standard deviation (population), in the channel's unit; 1.0 for
            a channel constant in the training data (std ≤ :data:`STD_FLOOR`), see notes.
        beta_mean: mean of β [rad].
        beta_std: standard deviation of β [rad] (1.0 when β is constant).
        notes: channels that got std 1.0 and why.
    """

    features: tuple[str, ...]
    mean: FloatArray
    std: FloatArray
    beta_mean: float
    beta_std: float
    notes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "features", tuple(self.features))
        channel_indices(self.features)
        for name in ("mean", "std"):
            arr = np.array(getattr(self, name), dtype=np.float64)
            if arr.shape != (len(self.features),) or not np.isfinite(arr).all():
                msg = f"Normalizer.{name} must be {len(self.features)} finite values, got {arr}"
                raise DatasetError(msg)
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "beta_mean", float(self.beta_mean))
        object.__setattr__(self, "beta_std", float(self.beta_std))
        stds = [*self.std.tolist(), self.beta_std]
        if not (all(s > 0.0 for s in stds) and math.isfinite(self.beta_mean + self.beta_std)):
            msg = f"Normalizer: std must be positive and finite, got {stds}"
            raise DatasetError(msg)

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Normalizer):
            return NotImplemented
        return self.to_dict() == other.to_dict()

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def fit(cls, runs: Sequence[Run], features: Sequence[str]) -> Normalizer:
        """Statistics over every finite sample of ``runs`` (pass the training runs only).

        Each channel uses its own finite values (a NaN in one channel does not remove the
        sample from the others). Raises DatasetError when a channel or β has none.
        """
        features = tuple(features)
        channel_indices(features)
        if not runs:
            raise DatasetError("Normalizer.fit: no runs")
        columns = [*features, BETA]
        values: dict[str, list[FloatArray]] = {c: [] for c in columns}
        for run in runs:
            if not run.samples.has_truth:
                msg = f"Normalizer.fit: run {run.name} has no ground truth β"
                raise DatasetError(msg)
            for c in features:
                values[c].append(np.asarray(getattr(run.samples, c), np.float64))
            values[BETA].append(run.samples.beta_rad())
        means: list[float] = []
        stds: list[float] = []
        notes: list[str] = []
        for c in columns:
            v = np.concatenate(values[c])
            v = v[np.isfinite(v)]
            if v.size == 0:
                msg = f"Normalizer.fit: {c} has no finite value in {len(runs)} run(s)"
                raise DatasetError(msg)
            mean, std = float(v.mean()), float(v.std())
            if std <= STD_FLOOR:
                notes.append(
                    f"{c} is constant ({mean:g}) in the training data: std set to 1.0, "
                    "so it is only centred"
                )
                std = 1.0
            means.append(mean)
            stds.append(std)
        return cls(
            features,
            np.array(means[:-1]),
            np.array(stds[:-1]),
            means[-1],
            stds[-1],
            tuple(notes),
        )

    def apply_features(self, x: npt.ArrayLike) -> FloatArray:
        """Normalise features ``x`` (..., F), columns in :attr:`features` order → float64."""
        arr = np.asarray(x, dtype=np.float64)
        if arr.ndim == 0 or arr.shape[-1] != len(self.features):
            want = len(self.features)
            msg = f"apply_features: last axis must hold {want} features, got shape {arr.shape}"
            raise DatasetError(msg)
        return (arr - self.mean) / self.std

    def apply_beta(self, beta_rad: npt.ArrayLike) -> FloatArray:
        """β [rad] → normalised β."""
        return (np.asarray(beta_rad, dtype=np.float64) - self.beta_mean) / self.beta_std

    def invert_beta(self, z: npt.ArrayLike) -> FloatArray:
        """Normalised β → β [rad]."""
        return np.asarray(z, dtype=np.float64) * self.beta_std + self.beta_mean

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (floats round-trip exactly through JSON)."""
        return {
            "features": list(self.features),
            "mean": self.mean.tolist(),
            "std": self.std.tolist(),
            "beta_mean": self.beta_mean,
            "beta_std": self.beta_std,
            "notes": list(self.notes),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Normalizer:
        """Inverse of :meth:`to_dict`; unknown or missing keys are an error."""
        keys = {"features", "mean", "std", "beta_mean", "beta_std", "notes"}
        unknown, missing = set(data) - keys, keys - {"notes"} - set(data)
        if unknown or missing:
            msg = f"normalizer: unknown keys {sorted(unknown)}, missing keys {sorted(missing)}"
            raise DatasetError(msg)
        try:
            return cls(
                tuple(str(f) for f in data["features"]),
                np.array(data["mean"], dtype=np.float64),
                np.array(data["std"], dtype=np.float64),
                float(data["beta_mean"]),
                float(data["beta_std"]),
                tuple(str(n) for n in data.get("notes", ())),
            )
        except (TypeError, ValueError) as err:
            if isinstance(err, DatasetError):
                raise
            msg = f"normalizer: bad value: {err}"
            raise DatasetError(msg) from None


# --- windows ----------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class WindowIndex:
    """Normalised samples of all runs back to back and the windows over them.

    Window ``i`` is ``x[ends[i] - window_steps + 1 : ends[i] + 1]`` (oldest row first);
    its target is ``y[ends[i]]``, the normalised β of its last sample. Within a run,
    windows start at samples 0, stride, 2·stride, ... (so the first window of every run
    long enough is always included, the last sample only when the grid reaches it);
    windows that would cross the run's end or contain a non-finite feature, and windows
    whose target β is non-finite, are left out. Runs are never joined: a window never
    spans two runs (or two segments of a bag split at a gap).

    Attributes:
        x: (S, F) float32 normalised features, S = samples of all runs.
        y: (S,) float32 normalised β at each sample (NaN where β is).
        ends: (N,) int64 index into x of the last sample of each window.
        run_of_window: (N,) int64 index into ``run_names`` of each window's run.
        run_names: names of the runs, in order.
        run_starts: (R + 1,) int64 offsets: run r is ``x[run_starts[r]:run_starts[r+1]]``.
        stamp_ns: (S,) int64 stamp of each sample [ns].
        beta_rad: (S,) float64 ground-truth β [rad] (unrounded, for metrics).
        features, window_steps, stride: as built.
        notes: runs too short for one window, or with windows left out.
    """

    x: npt.NDArray[np.float32]
    y: npt.NDArray[np.float32]
    ends: IntArray
    run_of_window: IntArray
    run_names: tuple[str, ...]
    run_starts: IntArray
    stamp_ns: IntArray
    beta_rad: FloatArray
    features: tuple[str, ...]
    window_steps: int
    stride: int
    notes: tuple[str, ...] = ()

    def __len__(self) -> int:
        return int(self.ends.shape[0])

    @classmethod
    def build(
        cls,
        runs: Sequence[Run],
        features: Sequence[str],
        normalizer: Normalizer,
        window_steps: int = 100,
        stride: int = 1,
    ) -> WindowIndex:
        """Normalise ``runs`` with ``normalizer`` and index their windows.

        Raises:
            DatasetError: features differ from the normalizer's, a run has no ground
                truth, or ``window_steps`` / ``stride`` < 1.
        """
        features = tuple(features)
        if features != normalizer.features:
            msg = f"features {features} differ from the normalizer's {normalizer.features}"
            raise DatasetError(msg)
        if window_steps < 1 or stride < 1:
            msg = f"window_steps and stride must be >= 1, got {window_steps} and {stride}"
            raise DatasetError(msg)
        xs, betas, stamps, ends, owners, notes = [], [], [], [], [], []
        offset = 0
        starts = [0]
        for r, run in enumerate(runs):
            if not run.samples.has_truth:
                msg = f"WindowIndex.build: run {run.name} has no ground truth β"
                raise DatasetError(msg)
            raw = _feature_matrix(run.samples, features)
            beta = run.samples.beta_rad()
            n = raw.shape[0]
            candidates = np.arange(window_steps - 1, n, stride, dtype=np.int64)
            bad = np.concatenate([[0], np.cumsum(~np.isfinite(raw).all(axis=1))])
            clean = (bad[candidates + 1] - bad[candidates + 1 - window_steps] == 0) & np.isfinite(
                beta[candidates]
            )
            valid = candidates[clean]
            if candidates.size == 0:
                notes.append(f"{run.name}: {n} samples, shorter than one window ({window_steps})")
            elif valid.size < candidates.size:
                notes.append(
                    f"{run.name}: {candidates.size - valid.size} of {candidates.size} windows "
                    "left out (non-finite feature or β)"
                )
            xs.append(raw)
            betas.append(beta)
            stamps.append(run.samples.stamp_ns)
            ends.append(valid + offset)
            owners.append(np.full(valid.shape, r, dtype=np.int64))
            offset += n
            starts.append(offset)
        width = len(features)
        x_all = np.concatenate(xs) if xs else np.empty((0, width))
        beta_all = np.concatenate(betas) if betas else np.empty(0)
        return cls(
            x=normalizer.apply_features(x_all).astype(np.float32),
            y=normalizer.apply_beta(beta_all).astype(np.float32),
            ends=np.concatenate(ends) if ends else np.empty(0, np.int64),
            run_of_window=np.concatenate(owners) if owners else np.empty(0, np.int64),
            run_names=tuple(run.name for run in runs),
            run_starts=np.array(starts, dtype=np.int64),
            stamp_ns=np.concatenate(stamps) if stamps else np.empty(0, np.int64),
            beta_rad=beta_all,
            features=features,
            window_steps=window_steps,
            stride=stride,
            notes=tuple(notes),
        )

    def batch(
        self, indices: npt.ArrayLike
    ) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
        """Windows ``indices`` as X (B, T, F) and their targets Y (B,), both float32."""
        last = self.ends[np.asarray(indices, dtype=np.int64)]
        rows = last[:, None] + np.arange(1 - self.window_steps, 1, dtype=np.int64)
        return self.x[rows], self.y[last]

    def to_torch(self, device: str | torch.device = "cpu") -> TorchWindows:
        """The samples and window ends as tensors on ``device`` (about 24 B per sample)."""
        import torch

        dev = torch.device(device)
        return TorchWindows(
            x=torch.from_numpy(self.x).to(dev),
            y=torch.from_numpy(self.y).to(dev),
            ends=torch.from_numpy(self.ends).to(dev),
            offsets=torch.arange(1 - self.window_steps, 1, dtype=torch.int64, device=dev),
        )


@dataclass(frozen=True, eq=False)
class TorchWindows:
    """:class:`WindowIndex` on a torch device; batches are gathered where the data lives.

    Attributes:
        x: (S, F) float32 normalised features.
        y: (S,) float32 normalised β.
        ends: (N,) int64 last-sample index of each window.
        offsets: (T,) int64 ``-T+1 .. 0``.
    """

    x: torch.Tensor
    y: torch.Tensor
    ends: torch.Tensor
    offsets: torch.Tensor

    def __len__(self) -> int:
        return int(self.ends.shape[0])

    def batch(self, idx: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """Windows ``idx`` (window numbers, any device) as X (B, T, F) and Y (B,)."""
        last = self.ends[idx.to(self.ends.device, non_blocking=True)]
        return self.x[last[:, None] + self.offsets], self.y[last]


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
