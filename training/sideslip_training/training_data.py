"""The data of one ``sideslip-train`` call: which bags train, validate and test (split by
bag or in time, never by window), the z-score statistics of the training part, the
window indices, and the choices that follow from the bags: the rate they were recorded
at, the window length in samples and the window stride.

Input a user can fix (a feature the bags lack, bags shared between parts, no window)
raises :class:`~.cli_errors.CliError`, its message naming the option.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np

from sideslip_msgs_py.data_source import is_simulated
from sideslip_msgs_py.mirror import mirrored
from sideslip_msgs_py.topic_map import TopicMap

from .cli_errors import CliError
from .config import DT_S, WINDOW_S
from .dataset import Run, load_runs
from .inputs import InputSpec
from .normalize import Normalizer
from .splits import split_in_time, split_runs
from .windows import WindowIndex

SAMPLES_PER_STRIDE: Final = 100_000
"""Without --stride, the stride is the profile's or one per this many training samples,
whichever is smaller."""


def small_data(train_samples: int, max_stride: int) -> bool:
    """Whether the training part is small: under ``max_stride`` × :data:`SAMPLES_PER_STRIDE`
    samples, where the stride rule takes more than the profile's share of windows (1 M
    samples with the quick profile; a recording of minutes, not a fleet)."""
    return train_samples < max_stride * SAMPLES_PER_STRIDE


def wants_mirror(mirror: str, train_samples: int, max_stride: int) -> bool:
    """--mirror ``yes``/``no``/``auto``: auto mirrors small training parts
    (:func:`small_data`), where it was measured to help (docs/training.md, "Small
    data"); on the 1.4-M-sample fleet it gave the same validation error at twice the cost."""
    if mirror not in ("auto", "yes", "no"):
        raise CliError(f"--mirror must be auto, yes or no, got {mirror!r}")
    return mirror == "yes" or (mirror == "auto" and small_data(train_samples, max_stride))


@dataclass(frozen=True)
class DataChoice:
    """The bags and how to split them, as the command line gave them.

    ``val`` and ``test`` are bags of their own (None: parts of ``data``); the fractions
    are of ``data``, the test part taken first. ``split`` is ``auto``, ``bag`` or
    ``time``; ``stride`` [samples] is None to choose it from the amount of data.
    """

    data: Sequence[str]
    val: Sequence[str] | None
    test: Sequence[str] | None
    split: str
    val_fraction: float
    test_fraction: float
    seed: int
    topic_map: Path | None
    stride: int | None
    mirror: str = "no"
    """``yes``, ``no`` or ``auto`` (:func:`wants_mirror`)."""
    mirror_val: bool = False
    """Also validate on every validation run mirrored left-right (``--mirror-val``)."""
    rehearse: Sequence[str] | None = None
    """Bags in the project's own topics (never read through ``topic_map``) added to the
    training part only: :func:`load_training_data`."""


@dataclass(frozen=True)
class TrainingData:
    """Runs of each part (``runs``: training + validation), the statistics, the window
    indices of training and validation at ``stride`` [samples], and how the parts were
    split (``bag`` or ``time``: what ``--refit auto`` and config.json go by)."""

    runs: list[Run]
    train_runs: list[Run]
    val_runs: list[Run]
    test_runs: list[Run]
    normalizer: Normalizer
    train: WindowIndex
    val: WindowIndex
    stride: int
    split: str
    mirror: bool = False
    val_mirrored: bool = False
    """``val_runs`` hold each validation run and its mirror image (``--mirror-val``)."""
    rehearsal_runs: tuple[Run, ...] = ()
    """The ``--rehearse`` runs, also in ``train_runs`` (after any mirrored ones)."""

    @property
    def recorded_train_runs(self) -> list[Run]:
        """``train_runs`` without the rehearsal: the recordings the model is fitted to."""
        rehearsal = {id(r) for r in self.rehearsal_runs}
        return [r for r in self.train_runs if id(r) not in rehearsal]

    @property
    def recordings(self) -> int:
        """How many training and validation bags are recordings, not simulated runs
        (:mod:`sideslip_msgs_py.data_source`); a bag and its mirror image count once."""
        return len(
            {r.bag for r in (*self.train_runs, *self.val_runs) if not is_simulated(r.run_metadata)}
        )

    @property
    def refit_runs(self) -> list[Run]:
        """The runs of the refit on training + validation: the validation runs mirrored
        as the training runs were, each mirror image once."""
        val = self.val_runs
        if self.mirror and not self.val_mirrored:
            val = with_mirrored(val)
        return [*self.train_runs, *val]


MIRROR_SUFFIX: Final = "~mirror"


def with_mirrored(runs: Sequence[Run]) -> list[Run]:
    """``runs`` followed by each run mirrored left-right (:mod:`sideslip_msgs_py.mirror`),
    named ``<name>~mirror`` and kept in its bag, so a split by bag never separates a run
    from its mirror image."""
    return [
        *runs,
        *(
            dataclasses.replace(
                r,
                name=r.name + MIRROR_SUFFIX,
                samples=mirrored(r.samples),
                recording=None if r.recording is None else mirrored(r.recording),
            )
            for r in runs
        ),
    ]


def split_mode(split: str, runs: Sequence[Run]) -> str:
    """``bag`` or ``time``: ``auto`` takes bags apart when there are 3 or more."""
    if split != "auto":
        return str(split)
    return "bag" if len({r.bag for r in runs}) >= 3 else "time"


def check_features(runs: Sequence[Run], channels: Sequence[str]) -> None:
    """Refuse a run in which a channel the model reads has no finite value at all."""
    for run in runs:
        for name in channels:
            column = np.asarray(getattr(run.samples, name))
            if not np.isfinite(column).any():
                raise CliError(f"feature {name} is missing from bag {run.path} (no finite value)")


def _split(
    choice: DataChoice, load: dict[str, Any], log: Callable[[str], None]
) -> tuple[list[Run], list[Run], list[Run], str]:
    """Training, validation and test runs (the last may be empty), and the split mode
    chosen on all of ``--data`` (``bag`` or ``time``)."""
    runs, report = load_runs(choice.data, **load)
    log(str(report))
    mode = split_mode(choice.split, runs)
    val_fraction = choice.val_fraction
    test_runs: list[Run] = []
    if choice.test:
        test_runs, test_report = load_runs(choice.test, **load)
        log(f"test: {test_report}")
    elif choice.test_fraction:
        if mode == "time":
            runs, test_runs = split_in_time(runs, choice.test_fraction, "test")
        else:
            runs, test_runs = split_runs(runs, choice.test_fraction, choice.seed + 1)
        # The validation fraction is of --data: of what the test part left, a larger share.
        val_fraction = val_fraction / (1.0 - choice.test_fraction)
    if choice.val:
        train_runs = runs
        val_runs, val_report = load_runs(choice.val, **load)
        log(f"validation: {val_report}")
    elif mode == "time":
        train_runs, val_runs = split_in_time(runs, val_fraction, "val")
    else:
        train_runs, val_runs = split_runs(runs, val_fraction, choice.seed)
    checks = [(train_runs, val_runs, "--val")] if choice.val else []
    checks += [([*train_runs, *val_runs], test_runs, "--test")] if choice.test else []
    for ours, other, flag in checks:
        shared = {r.path for r in ours} & {r.path for r in other}
        if shared:
            raise CliError(f"{flag} shares {len(shared)} bag(s) with --data, e.g. {min(shared)}")
    log(
        f"split by {mode}: {len(train_runs)} training, {len(val_runs)} validation, "
        f"{len(test_runs)} test run(s)"
    )
    return train_runs, val_runs, test_runs, mode


def load_training_data(
    choice: DataChoice,
    spec: InputSpec,
    window: int,
    *,
    max_stride: int,
    workers: int,
    progress: bool,
    log: Callable[[str], None],
    normalizer: Normalizer | None = None,
) -> TrainingData:
    """Read and split the bags, compute the UKF observer's columns where the inputs read
    them, and index the windows of ``window`` samples.

    Args:
        max_stride: the profile's stride [samples]; without ``choice.stride`` little
            data gets a smaller one.
        workers: processes for the UKF observer.
        normalizer: statistics to keep (fine-tuning); None fits them on the training runs.
    """
    topic_map = TopicMap.load(choice.topic_map) if choice.topic_map else None
    load = {"channels": spec.channels, "step_s": spec.dt_s, "topic_map": topic_map}
    train_runs, val_runs, test_runs, mode = _split(choice, load, log)
    recorded = sum(len(r) for r in train_runs)  # samples as recorded, before any mirror
    mirror = wants_mirror(choice.mirror, recorded, max_stride)
    if mirror:
        train_runs = with_mirrored(train_runs)
        log(f"mirror: {len(train_runs) // 2} training run(s) also mirrored left-right")
    if choice.mirror_val:
        # Simulated drives that open every manoeuvre to the same side (the fleet preset)
        # judge a model on one turning direction only; both ways, early stopping and the
        # epoch kept cannot favour a model that learnt the side (docs/evaluation/direction).
        val_runs = with_mirrored(val_runs)
        log(f"mirror: {len(val_runs) // 2} validation run(s) also mirrored left-right")
    needs_car = spec.needs_vehicle or spec.needs_observer
    rehearsal = _rehearsal(choice, load, [*train_runs, *val_runs, *test_runs], log, needs_car)
    train_runs = [*train_runs, *rehearsal]
    runs = [*train_runs, *val_runs]
    check_features(runs, spec.channels)
    if spec.needs_observer:
        from . import observer

        assert spec.observer is not None
        log(f"UKF observer over {len(runs)} run(s) (cached in {observer.cache_dir()})")
        observer.precompute(
            runs,
            spec.observer,
            spec.observer_params_file,
            car=spec.car,
            jobs=workers,
            progress=progress,
        )
    if normalizer is None:
        normalizer = Normalizer.fit(train_runs, spec, window)
    stride = choice.stride
    if stride is None:
        # Little data (a recording of minutes): every window, not every 10th; big data
        # (the fleet, over a million samples) keeps the profile's stride. The
        # recordings decide, not a rehearsal beside them: it would thin the validation.
        stride = min(max_stride, max(1, recorded // SAMPLES_PER_STRIDE))
    train = WindowIndex.build(train_runs, spec, normalizer, window, stride)
    val = WindowIndex.build(val_runs, spec, normalizer, window, stride)
    if len(train.ends) == 0 or len(val.ends) == 0:
        raise CliError(
            f"no windows of {window} samples: {len(train.ends)} for training, "
            f"{len(val.ends)} for validation (bags too short?)"
        )
    log(
        f"{len(train_runs)} training run(s), {len(train.ends)} windows; "
        f"{len(val_runs)} validation run(s), {len(val.ends)} windows (stride {stride})"
    )
    return TrainingData(
        runs,
        train_runs,
        val_runs,
        test_runs,
        normalizer,
        train,
        val,
        stride,
        mode,
        mirror,
        choice.mirror_val,
        tuple(rehearsal),
    )


def _rehearsal(
    choice: DataChoice,
    load: dict[str, Any],
    others: Sequence[Run],
    log: Callable[[str], None],
    needs_car: bool,
) -> list[Run]:
    """The ``--rehearse`` runs: simulated (or other labelled) driving beside the user's
    recordings, so that fine-tuning on a few minutes of one car's gentle driving does not
    forget what the start model knew about the limit (docs/evaluation/fit-bags,
    "Rehearsal"). They train only: validation, the test, early stopping, the intervals'
    calibration and their range stay on the recordings. Read in the project's own topics
    (a topic map is for the user's bags) at the model's step.

    Each takes its car from its own bag's record (a simulation's true parameters, as the
    fleet models were trained), whatever ``--car`` says for the recordings: rehearsing
    a corrected filter run with another car's file teaches corrections the node will
    never need (measured: docs/evaluation/fit-bags, "Rehearsal")."""
    if not choice.rehearse:
        return []
    runs, report = load_runs(choice.rehearse, **{**load, "topic_map": None})
    runs = [dataclasses.replace(r, car_source="recorded") for r in runs]
    log(f"rehearsal: {report}")
    shared = {r.path for r in runs} & {r.path for r in others}
    if shared:
        raise CliError(
            f"--rehearse shares {len(shared)} bag(s) with --data, --val or --test, e.g. "
            f"{min(shared)}: rehearsal is other driving than the recordings'"
        )
    if not runs:
        raise CliError(f"--rehearse {' '.join(choice.rehearse)}: no bag read")
    unknown = [r.name for r in runs if not isinstance(r.run_metadata.get("vehicle"), dict)]
    if needs_car and unknown:
        raise CliError(
            f"--rehearse: {unknown[0]} records no car, and the model reads the car: a "
            "rehearsal run takes its own car, not the recordings' (sideslip-generate "
            "bags record theirs)"
        )
    return runs


def sample_period_s(runs: Sequence[Run]) -> float:
    """The bags' common sample period [s] (median stamp step); mixed rates are refused."""
    periods = {
        r.name: float(np.median(np.diff(r.samples.stamp_ns))) * 1e-9
        for r in runs
        if len(r.samples) > 1
    }
    if not periods:
        raise CliError("no bag has two samples: no sample period")
    common = float(np.median(list(periods.values())))
    odd = [f"{n} ({p * 1e3:.2f} ms)" for n, p in periods.items() if abs(p / common - 1) > 0.02]
    if odd:
        raise CliError(
            f"bags at another rate than {common * 1e3:.2f} ms: {', '.join(odd[:5])}; a model "
            "sees a fixed step, train on one rate"
        )
    return common


def recorded_rate_hz(data: Sequence[str], topic_map: Path | None) -> float:
    """The rate [Hz] the bags under ``data`` were recorded at (the median over the first
    five), so that a model runs at its car's own rate; within 1 % of the contract's
    400 Hz, 400."""
    from sideslip_msgs_py.bag import read_bag
    from sideslip_msgs_py.resample import measured_step_s
    from sideslip_msgs_py.topic_map_read import read_mapped_bag

    from .dataset import find_bags

    mapping = TopicMap.load(topic_map) if topic_map else None
    steps = []
    for path in find_bags(data)[:5]:
        try:
            samples = (
                read_bag(path).samples
                if mapping is None
                else read_mapped_bag(path, mapping).samples
            )
        except Exception:  # an unreadable bag is reported by load_runs
            continue
        step = measured_step_s(samples.stamp_ns)
        if step:
            steps.append(step)
    if not steps:
        return 1.0 / DT_S
    rate = 1.0 / float(np.median(steps))
    return 1.0 / DT_S if abs(rate * DT_S - 1.0) <= 0.01 else round(rate, 1)


def window_steps(step_s: float, *, steps: int | None, seconds: float | None) -> int:
    """The window in samples: ``steps`` (--window-steps), or ``seconds`` (--window-s,
    default the paper's 0.25 s) at the model's step ``step_s`` [s]: the horizon in
    seconds stays the same whatever the rate."""
    if steps is not None:
        if steps < 2:
            raise CliError(f"--window-steps must be >= 2, got {steps}")
        return int(steps)
    window_s = WINDOW_S if seconds is None else seconds
    n = round(window_s / step_s)
    if not (math.isfinite(window_s) and n >= 2):
        raise CliError(f"--window-s {window_s:g} s is under two samples at {1 / step_s:g} Hz")
    return n
