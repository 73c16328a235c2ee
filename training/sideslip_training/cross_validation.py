"""How many epochs to train, chosen by K-fold cross-validation over the user's bags
(``sideslip-train --folds K``) instead of on one validation split.

Why: fine-tuning on a few minutes of a car's own driving, a 20 % validation split is
about a minute, six or seven drives, and it judged wrongly: it kept the start model
where the fine-tuned one was 38 % better on the car's other drives
(docs/evaluation/scenario-driving, section 5). Here every training and validation bag
validates once: K trainings, each on the other folds, each scored on its own fold at
every epoch; the pooled out-of-fold MAE (window-weighted) over the epochs chooses the
epoch count, and, when fine-tuning, whether any epoch beats the start at all (epoch 0).

The folds: whole bags (a bag and its mirror image together), assigned by a seeded hash
rank of the bag name dealt round-robin, as :func:`~.splits.split_runs` ranks them; with
a split in time (one long recording) every run is cut into K consecutive blocks, block
k of each run going to fold k (each block a run of its own, as the split in time makes
them, that remembers its recording: the UKF observer runs through the cut, as the node
does; :func:`~.dataset.cut`). Where the training mirrors
its runs, a held-out fold holds its runs' mirror images too, so that no fold is scored
on one turning direction only. ``--rehearse`` runs train in every fold and validate in
none. The z-score statistics stay the training's (the start model's with
``--normalization keep``).

Each fold stops early on its own fold (the profile's patience); past its last epoch a
fold counts with its last epoch's MAE, which is no better than its best, so an epoch
count beyond where a fold stopped is charged for it.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from .cli_errors import CliError
from .dataset import Run, cut
from .inputs import InputSpec
from .normalize import Normalizer
from .splits import bag_rank
from .trainer import TrainConfig, TrainResult, train_model
from .windows import WindowIndex


@dataclass(frozen=True)
class FoldRecord:
    """One fold's training: its validation runs and windows, the start's MAE on them
    (the lower of alone and mirror-averaged, as the handover scores it; None from
    scratch), and the MAE [deg] at every epoch it ran."""

    fold: int
    val_runs: int
    val_windows: int
    start_mae_deg: float | None
    epoch_mae_deg: list[float]
    seconds: float
    start_mae_forms: dict[str, float] = field(default_factory=dict)
    """The start's MAE per way the node may run it (``alone``, ``averaged``)."""


@dataclass
class CrossValidation:
    """The folds and what they chose: ``epochs`` (0 when fine-tuning and no epoch count
    beat the start out of fold), the pooled out-of-fold MAE [deg] per epoch count
    (``curve[e - 1]`` for e epochs) and of the start."""

    folds: list[FoldRecord] = field(default_factory=list)
    curve: list[float] = field(default_factory=list)
    start_mae_deg: float | None = None
    epochs: int = 0
    results: list[TrainResult] = field(default_factory=list, repr=False)
    """Each fold's training, its best epoch on its own fold kept (the start's weights
    when none beat them): written to the run folder, not into the summary."""

    @property
    def best_mae_deg(self) -> float:
        """The pooled out-of-fold MAE of the choice (the start's when it was kept)."""
        if self.epochs == 0:
            assert self.start_mae_deg is not None
            return self.start_mae_deg
        return self.curve[self.epochs - 1]

    def summary(self) -> dict[str, Any]:
        return {
            "folds": len(self.folds),
            "epochs": self.epochs,
            "kept_start": self.epochs == 0,
            "pooled_mae_deg": self.best_mae_deg,
            "start_pooled_mae_deg": self.start_mae_deg,
            "pooled_curve_deg": self.curve,
            "per_fold": [dataclasses.asdict(f) for f in self.folds],
        }


def fold_runs(runs: Sequence[Run], folds: int, mode: str, seed: int) -> list[list[Run]]:
    """``runs`` dealt into ``folds`` groups: by bag (``mode`` ``bag``) or, in time, each
    run's k-th block of consecutive samples to group k.

    Raises:
        CliError: fewer than 2 folds, or fewer bags than folds when dealing by bag.
    """
    if folds < 2:
        raise CliError(f"--folds must be >= 2 to cross-validate, got {folds}")
    groups: list[list[Run]] = [[] for _ in range(folds)]
    if mode == "bag":
        bags = sorted({r.bag for r in runs}, key=lambda b: bag_rank(seed, b))
        if len(bags) < folds:
            raise CliError(
                f"--folds {folds} needs at least {folds} bags to deal out, got {len(bags)}: "
                "give fewer folds, or --split time for one long recording"
            )
        fold_of = {bag: i % folds for i, bag in enumerate(bags)}
        for run in runs:
            groups[fold_of[run.bag]].append(run)
        return groups
    for run in runs:
        n = len(run)
        cuts = [round(k * n / folds) for k in range(folds + 1)]
        for k in range(folds):
            if cuts[k + 1] > cuts[k]:
                groups[k].append(cut(run, cuts[k], cuts[k + 1], f"{run.name}#{k}"))
    return groups


def pooled_curve(folds: Sequence[FoldRecord]) -> list[float]:
    """The window-weighted mean over the folds of the MAE after e epochs, for e = 1 up to
    the longest fold; a fold that stopped earlier counts with its last epoch."""
    longest = max(len(f.epoch_mae_deg) for f in folds)
    total = sum(f.val_windows for f in folds)
    curve = []
    for e in range(longest):
        s = sum(f.val_windows * f.epoch_mae_deg[min(e, len(f.epoch_mae_deg) - 1)] for f in folds)
        curve.append(s / total)
    return curve


def pooled_start(folds: Sequence[FoldRecord]) -> float | None:
    """The start's pooled MAE: each way of running it (alone, mirror-averaged) pooled
    over the folds, the lower of the two, as the handover's bar on one validation set;
    None from scratch or when a fold has no finite figure."""
    forms = set.intersection(*(set(f.start_mae_forms) for f in folds)) if folds else set()
    total = sum(f.val_windows for f in folds)
    pooled = [sum(f.val_windows * f.start_mae_forms[form] for f in folds) / total for form in forms]
    finite = [x for x in pooled if math.isfinite(x)]
    return min(finite) if finite and len(finite) == len(pooled) else None


def choose_epochs(curve: Sequence[float], start_mae_deg: float | None) -> int:
    """The epoch count of the lowest pooled MAE; 0 (keep the start) when fine-tuning and
    no count is below the start's pooled MAE.

    Raises:
        ValueError: no epoch count with a finite pooled MAE (the trainings diverged).
    """
    finite = [e for e in range(len(curve)) if math.isfinite(curve[e])]
    if not finite:
        raise ValueError("no epoch with a finite out-of-fold MAE: training diverged")
    best = min(finite, key=lambda e: (curve[e], e))
    if start_mae_deg is not None and not curve[best] < start_mae_deg:
        return 0
    return best + 1


def check_windows(groups: Sequence[Sequence[Run]], window: int) -> None:
    """Refuse folds of which one has no run of ``window`` samples (before any training).

    Raises:
        CliError: naming the fold and the window.
    """
    for k, held in enumerate(groups):
        if not any(len(r) >= window for r in held):
            raise CliError(
                f"--folds {len(groups)}: fold {k + 1} has no run of {window} samples (one "
                "window): give fewer folds or longer runs"
            )


def cross_validate(
    cfg: TrainConfig,
    groups: Sequence[Sequence[Run]],
    *,
    spec: InputSpec,
    normalizer: Normalizer,
    window: int,
    stride: int,
    rehearsal: Sequence[Run] = (),
    init_state: Mapping[str, Any] | None = None,
    deployed_mirror: tuple[bool, bool] = (False, False),
    log: Callable[[str], None] = lambda _: None,
) -> CrossValidation:
    """Train once per fold of ``groups`` (:func:`fold_runs`; on the other folds plus
    ``rehearsal``, from ``init_state`` when fine-tuning) and choose the epoch count on
    the pooled out-of-fold MAE.

    Raises:
        CliError: a fold without a window to validate on or train on.
        ValueError: every fold's training diverged.
    """
    folds = len(groups)
    cv = CrossValidation()
    for k, held in enumerate(groups):
        others = [r for j, g in enumerate(groups) if j != k for r in g]
        train = WindowIndex.build([*others, *rehearsal], spec, normalizer, window, stride)
        val = WindowIndex.build(held, spec, normalizer, window, stride)
        if len(val.ends) == 0 or len(train.ends) == 0:
            raise CliError(
                f"fold {k + 1} of {folds}: {len(val.ends)} windows to validate on, "
                f"{len(train.ends)} to train on (runs too short for {folds} folds?)"
            )
        result: TrainResult = train_model(
            cfg,
            train,
            val,
            normalizer,
            init_state=init_state,
            deployed_mirror=deployed_mirror,
        )
        record = FoldRecord(
            fold=k + 1,
            val_runs=len(held),
            val_windows=len(val.ends),
            start_mae_deg=result.start_val_mae_deg,
            epoch_mae_deg=[r.val_mae_deg for r in result.history],
            seconds=result.seconds,
            start_mae_forms=dict(result.start_val_mae_forms),
        )
        cv.folds.append(record)
        cv.results.append(result)
        start = "" if record.start_mae_deg is None else f", start {record.start_mae_deg:.4f}"
        log(
            f"fold {k + 1}/{folds}: {len(held)} run(s), {len(val.ends)} windows{start}, "
            f"best {min(record.epoch_mae_deg):.4f} deg at epoch "
            f"{1 + record.epoch_mae_deg.index(min(record.epoch_mae_deg))} of "
            f"{len(record.epoch_mae_deg)} ({record.seconds:.0f} s)"
        )
    cv.curve = pooled_curve(cv.folds)
    if init_state is not None:
        cv.start_mae_deg = pooled_start(cv.folds)
    cv.epochs = choose_epochs(cv.curve, cv.start_mae_deg)
    return cv
