"""The options of ``sideslip-fit --bags`` and the recipes it trains with: what a user can
set, the defaults and the one-line refusals of options that do not go together.
:mod:`.fit_bags` runs the fit."""

from __future__ import annotations

import argparse
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from .cli_errors import CliError
from .weight_interpolation import check_alpha

DEFAULT_TEST_FRACTION: Final = 0.3
"""The share of every recording kept for the test (the issue's 70/30 split in time)."""
DEFAULT_REHEARSAL_RUNS: Final = 0
"""Simulated runs of cars like the described one trained beside the recordings
(``--rehearse``)."""
DEFAULT_INTERPOLATION: Final = 0.5
"""The fitted weights kept half way from the start model's (``sideslip-train
--interpolate``): chosen on validation cars' other drives with ``fleet_ukf_measurable``
(O5U) as the start (docs/evaluation/fit-bags, "Half way back to the start")."""
START_INTERPOLATION: Final = {"fleet_ukf_merged": 0.25, "fleet_ukf_ensemble": 0.5}
"""Starts with a share of their own, chosen for that start on validation cars' other
drives. ``fleet_ukf_ensemble`` (since 2026-12-07; fitted at 3e-4 with the UKF observer
running through the cut into the validation stretch, as the node runs it), fitted to
5 minutes of 8 validation cars' driving, scored on their 18 benchmark drives each:
α 0.5 0.0267°, 0.25 0.0271°, 1 0.0297°, the start alone 0.0284° (0.5 better than 0.25
on 6 of 8, than the start on 6 of 8; docs/evaluation/fit-bags/through-the-cut.json).
Until then 0.25, chosen the same way on fits whose observer restarted at the cut
(0.0276° at 3e-4; docs/models/fleet_ukf_ensemble/finetune-lr-validation.json).
``fleet_ukf_merged`` on the same cars and drives (with restarts): α 0.25 0.0290°, 0.5
0.0307°, the start alone 0.0301° (0.25 better than 0.5 on 6 of 8;
docs/models/fleet_ukf_merged/finetune-alpha-validation.json)."""


START_LEARNING_RATE: Final = {"fleet_ukf_ensemble": 3e-4}
"""Starts fine-tuned at a learning rate of their own (``sideslip-train --learning-rate``;
other starts: the profile's, 1e-3). ``fleet_ukf_ensemble`` fitted to 5 minutes of 8
validation cars' driving, scored on their 18 benchmark drives each, α 0.25: 3e-4 0.0276°,
1e-3 0.0283° (better on 6 of 8, level on 1; the worst car 27 % worse than the start
instead of 42 %), at about 1.8 times the epochs
(docs/models/fleet_ukf_ensemble/finetune-lr-validation.json)."""


@dataclass(frozen=True)
class BagRecipe:
    """How ``sideslip-train`` fine-tunes on the recordings."""

    train_args: tuple[str, ...]
    summary: str


BAG_RECIPES: Final = {
    # Measured on the six held-out cars with 5 minutes each (docs/evaluation/
    # held-out-curve, "the user's path"): ~1.5 min per training on 2 cores; from the
    # retrained start with --interpolate 0.5, 18 % better than the same recipe from
    # scratch on average (three seeds), never worse than the shipped model.
    "quick": BagRecipe(
        ("--profile", "quick", "--stride", "10", "--mirror", "no"),
        "sideslip-train --profile quick --stride 10 --mirror no",
    ),
    # sideslip-train's small-data defaults (every window, runs mirrored left-right below
    # 1 M samples): 20 times the windows; on one validation car 1977 s against 266 s,
    # test-part MAE 0.0192 against 0.0244 (docs/evaluation/fit-bags).
    "thorough": BagRecipe(
        ("--profile", "quick"),
        "sideslip-train --profile quick (small-data defaults: stride 1, mirrored runs)",
    ),
}


def add_bag_arguments(p: argparse.ArgumentParser) -> None:
    """The options of the recordings path."""
    p.add_argument(
        "--bags",
        nargs="+",
        metavar="BAG",
        help="fit to the car's own recordings with a reference β (bags or folders) instead "
        "of simulating cars like it: identify the UKF's axles (measurable), fine-tune, "
        "test on each recording's last --test-fraction",
    )
    p.add_argument(
        "--topic-map",
        type=Path,
        metavar="FILE",
        help="with --bags: read bags (and --test-bags) recorded with other topics "
        "(docs/topic-maps.md)",
    )
    p.add_argument(
        "--test-fraction",
        type=float,
        default=None,
        help=f"with --bags: the last share of every recording kept for the test "
        f"(default {DEFAULT_TEST_FRACTION:g})",
    )
    p.add_argument(
        "--rehearse",
        type=int,
        metavar="RUNS",
        default=None,
        help="with --bags: simulated runs (fleet manoeuvres up to the limit, μ 0.3-1.0) of "
        "cars like the description's, trained beside the recordings but never validated, "
        "tested or calibrated on, so that the fit keeps what the shipped model knew "
        f"beyond the recordings (default {DEFAULT_REHEARSAL_RUNS}; 0: none; about 9 s "
        "of driving each; docs/evaluation/fit-bags, 'Rehearsal')",
    )
    p.add_argument(
        "--interpolate",
        type=float,
        metavar="ALPHA",
        default=None,
        help="with --bags: keep the start model's weights moved this share of the way to "
        "the fine-tuned ones (default "
        + ", ".join(f"{a:g} from {name}" for name, a in START_INTERPOLATION.items())
        + f", {DEFAULT_INTERPOLATION:g} from other starts: better on other drives than the "
        "plain fine-tuning (1) and the start (0) on validation cars; "
        "docs/evaluation/fit-bags)",
    )
    p.add_argument(
        "--folds",
        type=int,
        metavar="K",
        default=None,
        help="with --bags: choose the fine-tune's epoch count, or keeping the start, by "
        "K-fold cross-validation over the part before the test (each recording cut into K "
        "blocks in time; sideslip-train --folds) instead of on the stretch just before the "
        "test, and calibrate σ on all of that part out of fold: K + 2 trainings instead "
        "of 1-2 (default 1: that stretch)",
    )
    p.add_argument(
        "--test-bags",
        nargs="+",
        metavar="BAG",
        help="with --bags: other recordings of the car (bags or folders; other roads and "
        "manoeuvres), scored whole after the fit and never used to identify, train, "
        "choose or calibrate: the card's check on drives the fit has not seen",
    )


def check_bag_arguments(args: argparse.Namespace) -> float:
    """Refuse options that do not go together; the test fraction to use."""
    if args.bags is None:
        names = ("topic_map", "test_fraction", "test_bags", "rehearse", "interpolate", "folds")
        for name in names:
            if getattr(args, name) is not None:
                raise CliError(f"--{name.replace('_', '-')} needs --bags")
        return 0.0
    for name in ("cars", "test_runs"):
        if getattr(args, name) is not None:
            raise CliError(f"--{name.replace('_', '-')} is for simulated fits, not with --bags")
    if args.rehearse is not None and args.rehearse < 0:
        raise CliError(f"--rehearse must be >= 0 runs, got {args.rehearse}")
    if args.interpolate is not None:
        try:
            check_alpha(args.interpolate)
        except ValueError as err:
            raise CliError(str(err)) from None
    if args.folds is not None and args.folds < 1:
        raise CliError(f"--folds must be 1 (no cross-validation) or >= 2, got {args.folds}")
    fraction = DEFAULT_TEST_FRACTION if args.test_fraction is None else args.test_fraction
    if not (0.0 < fraction < 1.0 and math.isfinite(fraction)):
        raise CliError(f"--test-fraction must be in (0, 1), got {args.test_fraction}")
    return fraction


def interpolation(args: argparse.Namespace, start: str) -> float:
    """``--interpolate``'s share, or the default for the ``start`` model (a shipped name
    or a file)."""
    if args.interpolate is not None:
        return float(args.interpolate)
    return START_INTERPOLATION.get(_start_name(start), DEFAULT_INTERPOLATION)


def learning_rate(args: argparse.Namespace, start: str) -> float | None:
    """``--learning-rate``, or the ``start`` model's own (None: the profile's)."""
    if args.learning_rate is not None:
        return float(args.learning_rate)
    return START_LEARNING_RATE.get(_start_name(start))


def _start_name(start: str) -> str:
    """The shipped name of a start given by name or as a file."""
    return Path(start).name.removesuffix(".safetensors")


def rehearsal_runs(args: argparse.Namespace) -> int:
    """How many rehearsal runs the fit trains beside the recordings."""
    return DEFAULT_REHEARSAL_RUNS if args.rehearse is None else int(args.rehearse)


def folds(args: argparse.Namespace) -> int:
    """How many folds choose the fine-tune (1: the stretch before the test part)."""
    return 1 if args.folds is None else int(args.folds)
