"""``sideslip-train``: bags → a trained, exported model. This module parses the options
and reports; what a call will do is resolved in :mod:`.train_plan` (data in
:mod:`.training_data`), the PSO search is in :mod:`.search`, the refit and the model's
metadata in :mod:`.final_model`, ``sideslip-evaluate`` in :mod:`.evaluate_cli`.

The house CLI pattern: ``--help`` reads like a manual, progress bars on
anything long, ``--out`` never overwritten without ``--force``, and bad input (empty
data, a feature the bags lack, an existing output) is one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from sideslip_msgs_py.artifact import ArtifactError, ModelMetadata
from sideslip_msgs_py.features import FeatureError

from .cli_errors import EXIT_BAD_INPUT, CliError
from .cross_validation import CrossValidation, check_windows, cross_validate, fold_runs
from .dataset import DatasetError, Run
from .evaluate import json_ready
from .export import export_model
from .final_model import deployed_mirror, model_metadata, refit, wants_refit
from .init_model import InitError
from .run_folder import start_run_folder
from .search import run_pso
from .train_args import train_parser
from .train_intervals import calibrate_selection, interval_mode
from .train_metrics import pooled_test_metrics, val_metrics
from .train_plan import TrainPlan, plan_training, run_config
from .trainer import EpochRecord, TrainResult, train_model
from .weight_interpolation import interpolate_toward


class _Stop(Exception):
    """A failure once the run folder is made: its one-line message and the exit code."""

    def __init__(self, message: str, exit_code: int) -> None:
        super().__init__(message)
        self.exit_code = exit_code


def _error(err: object, exit_code: int) -> int:
    print(f"sideslip-train: error: {err}", file=sys.stderr)
    return exit_code


def train_main(argv: Sequence[str] | None = None) -> int:
    """``sideslip-train``; the exit code: 0, 2 for input a user can fix, 1 when the
    training diverged or the model could not be written."""
    args = train_parser().parse_args(argv)
    log = (lambda *_: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    started = time.perf_counter()
    try:
        plan = plan_training(args, log)
        if args.folds != 1 and (args.pso or args.folds < 2):
            raise CliError(
                f"--folds {args.folds}: cross-validation takes 2 or more folds, and not "
                "with --pso (each particle is selected on the validation split)"
                if args.pso
                else f"--folds must be 1 (the validation split) or >= 2, got {args.folds}"
            )
        if args.epochs is not None:
            _check_epochs(args)
        groups = None
        if args.folds > 1:  # dealt, and refused, before the run folder is made
            groups = fold_runs(_cv_runs(plan), args.folds, plan.data.split, args.seed)
            check_windows(groups, plan.window)
        intervals = interval_mode(args.intervals, plan, groups)
    except (CliError, DatasetError, FeatureError, ImportError, ValueError, InitError) as err:
        return _error(err, EXIT_BAD_INPUT)
    command = " ".join(["sideslip-train", *(argv if argv is not None else sys.argv[1:])])
    config = run_config(args, command, plan)
    try:
        start_run_folder(plan.run_dir, config, resume=args.resume)
    except CliError as err:  # --resume of a run started otherwise
        return _error(err, EXIT_BAD_INPUT)
    try:
        result, pso_info, cv = _train(args, plan, log, groups)
        fine_tuned_val_mae = result.best_val_mae_deg
        _toward_start(result, plan, args.interpolate, log)

        def metadata(result: TrainResult, metrics: dict[str, Any]) -> ModelMetadata:
            return model_metadata(
                plan,
                result,
                architecture=args.model,
                normalization=args.normalization,
                digest=config["data_digest"],
                metrics=metrics,
                pso_info=pso_info,
                command=command,
                wall_s=time.perf_counter() - started,
            )

        # Before the refit: the validation runs are still unseen by the selected model.
        uncertainty, calibration = calibrate_selection(
            intervals,
            plan,
            result.model,
            metadata(result, {}),
            args.seed,
            log,
            args.intervals,
            folds=_calibration_folds(cv, groups, result, plan, args.interpolate),
        )
        result, metrics = _validate_and_refit(args, plan, config["split"], result, log, cv)
        if calibration is not None:
            metrics["interval_calibration"] = calibration
        if args.epochs is not None:
            metrics["fixed_epochs"] = args.epochs
        if args.interpolate < 1.0 and result.best_epoch > 0:
            metrics["interpolate"] = args.interpolate
            metrics["fine_tuned_val_mae_deg"] = fine_tuned_val_mae
        meta = replace(metadata(result, metrics), uncertainty=uncertainty)
        _export(args.out, result, meta)
        if cv is not None:
            _export_folds(plan.run_dir, cv, metadata)
    except _Stop as stop:
        return _error(stop, stop.exit_code)
    _warn_if_still_improving(result, metrics)
    if plan.data.test_runs:
        metrics["test"] = pooled_test_metrics(args.out, plan.data.test_runs, log, plan.spec)
    total = time.perf_counter() - started
    summary = {**metrics, "wall_s": total, "out": str(args.out), "run_dir": str(plan.run_dir)}
    # Strict JSON for any reader: an undefined figure (R² of a straight run) is null.
    text = json.dumps(json_ready(summary), indent=2, allow_nan=False)
    (plan.run_dir / "metrics.json").write_text(text + "\n")
    log(
        f"wrote {args.out}: validation MAE {metrics['val_mae_deg']:.4f} deg, "
        f"RMSE {metrics['val_rmse_deg']:.4f} deg, {total:.0f} s"
    )
    return 0


def _train(
    args: argparse.Namespace,
    plan: TrainPlan,
    log: Callable[[str], None],
    groups: list[list[Run]] | None = None,
) -> tuple[TrainResult, dict[str, Any] | None, CrossValidation | None]:
    """The selected training, the PSO record and the cross-validation: PSO's best
    particle, or one training (from --init's weights when fine-tuning), its epoch count
    chosen out of fold over ``groups`` (--folds) when given."""
    data = plan.data
    if args.pso:
        from .pso import PsoError

        try:
            result, pso_info = run_pso(
                args,
                plan.profile,
                plan.base,
                data.train,
                data.val,
                data.normalizer,
                plan.run_dir,
                log,
            )
        except PsoError as err:  # e.g. a damaged or foreign pso_state.json on --resume
            raise _Stop(str(err), EXIT_BAD_INPUT) from err
        return result, pso_info, None
    try:
        if groups is not None:
            cv = _cross_validate(args, plan, log, groups)
            return _train_chosen(plan, cv, args.quiet), None, cv
        if args.epochs is not None:
            return _train_fixed(plan, args.epochs, args.quiet), None, None
        return _train_one(plan, args.quiet), None, None
    except ValueError as err:  # diverged: no epoch to export
        raise _Stop(str(err), 1) from err


def _cross_validate(
    args: argparse.Namespace,
    plan: TrainPlan,
    log: Callable[[str], None],
    groups: list[list[Run]],
) -> CrossValidation:
    """--folds: the epoch count chosen out of fold over ``groups``, the training and
    validation runs dealt into folds (the rehearsal trains in every fold); the record in
    cross_validation.json."""
    data = plan.data
    log(f"cross-validation: {args.folds} folds by {data.split}")
    # Blocks cut in time read their recordings' observer columns, which the data's
    # loading has already filtered (dataset.cut): nothing to precompute here.
    try:
        cv = cross_validate(
            plan.base,
            groups,
            spec=plan.spec,
            normalizer=data.normalizer,
            window=plan.window,
            stride=data.stride,
            rehearsal=data.rehearsal_runs,
            init_state=plan.init_state(),
            deployed_mirror=deployed_mirror(plan),
            log=log,
        )
    except CliError as err:
        raise _Stop(str(err), EXIT_BAD_INPUT) from err
    text = json.dumps(json_ready(cv.summary()), indent=2, allow_nan=False)
    (plan.run_dir / "cross_validation.json").write_text(text + "\n")
    start = "" if cv.start_mae_deg is None else f" (the start: {cv.start_mae_deg:.4f})"
    log(
        f"cross-validation chose {cv.epochs} epoch(s): pooled out-of-fold MAE "
        f"{cv.best_mae_deg:.4f} deg{start}"
    )
    return cv


def _calibration_folds(
    cv: CrossValidation | None,
    groups: list[list[Run]] | None,
    selected: TrainResult,
    plan: TrainPlan,
    alpha: float,
) -> list[tuple[list[Run], Any]] | None:
    """--folds: what the intervals are calibrated on, each fold's runs with the network
    that did not train on it (the fold's own, at its best epoch on it, moved toward the
    start as the exported model is with --interpolate ``alpha``); every run with the
    start when the start was kept (it trained on none of them). None without folds: the
    validation split."""
    if cv is None or groups is None:
        return None
    if cv.epochs == 0:
        return [([r for g in groups for r in g], selected.model)]
    start = plan.init_state()
    nets = []
    for result in cv.results:
        net = result.model
        if start is not None and alpha < 1.0 and result.best_epoch > 0:
            net = interpolate_toward(copy.deepcopy(net), start, alpha)
        nets.append(net)
    return list(zip(groups, nets, strict=True))


def _cv_runs(plan: TrainPlan) -> list[Run]:
    """The runs --folds deals out: training and validation, mirrored as the training
    runs are, without the rehearsal (which trains in every fold)."""
    rehearsal = {id(r) for r in plan.data.rehearsal_runs}
    return [r for r in plan.data.refit_runs if id(r) not in rehearsal]


def _train_chosen(plan: TrainPlan, cv: CrossValidation, quiet: bool) -> TrainResult:
    """The training part trained for the epoch count cross-validation chose (the model
    the intervals are calibrated with and the validation split scores, before the
    refit), or the start model itself when it chose none."""
    if cv.epochs == 0:
        assert plan.init is not None and cv.start_mae_deg is not None
        return TrainResult(
            model=copy.deepcopy(plan.init.net).cpu().eval(),
            best_epoch=0,
            best_val_mae_deg=cv.start_mae_deg,
            start_val_mae_deg=cv.start_mae_deg,
            stopped_early=True,
        )
    result = _train_fixed(plan, cv.epochs, quiet)
    # Still improving only when the chosen count is the longest fold's last epoch at
    # the profile's limit: then more epochs might have been better out of fold.
    result.stopped_early = not (
        cv.epochs == len(cv.curve) and len(cv.curve) >= plan.base.max_epochs
    )
    return result


def _check_epochs(args: argparse.Namespace) -> None:
    """--epochs N: a count given, so nothing else may choose or cap it."""
    if args.epochs < 1:
        raise CliError(f"--epochs must be 1 or more, got {args.epochs}")
    for given, name in ((args.pso, "--pso"), (args.folds != 1, "--folds"),
                        (args.max_epochs is not None, "--max-epochs")):  # fmt: skip
        if given:
            raise CliError(
                f"--epochs {args.epochs} with {name}: --epochs gives the count that "
                f"{name} would choose or cap; give one of them"
            )


def _train_fixed(plan: TrainPlan, epochs: int, quiet: bool) -> TrainResult:
    """--epochs: the training part trained for exactly ``epochs`` epochs, the last one
    kept (the model the intervals are calibrated with and the validation split scores,
    before the refit). Never "still improving": nothing was chosen."""
    fixed = replace(plan, base=replace(plan.base, max_epochs=epochs))
    result = _train_one(fixed, quiet, keep_last=True)
    result.stopped_early = True
    return result


def _train_one(plan: TrainPlan, quiet: bool, *, keep_last: bool = False) -> TrainResult:
    """One training with a progress bar over the epochs (on stderr, off with --quiet);
    ``keep_last``: all ``max_epochs``, the last one kept (an epoch count chosen before)."""
    from tqdm import tqdm

    cfg, data = plan.base, plan.data
    bar = tqdm(total=cfg.max_epochs, unit="epoch", disable=quiet, file=sys.stderr)

    def on_epoch(r: EpochRecord) -> None:
        bar.set_postfix(val_mae_deg=f"{r.val_mae_deg:.4f}", win_per_s=f"{r.windows_per_s:.0f}")
        bar.update()

    try:
        return train_model(
            cfg,
            data.train,
            data.val,
            data.normalizer,
            on_epoch=on_epoch,
            init_state=plan.init_state(),
            keep_last=keep_last,
            deployed_mirror=deployed_mirror(plan),
        )
    finally:
        bar.close()


def _validate_and_refit(
    args: argparse.Namespace,
    plan: TrainPlan,
    split: str,
    result: TrainResult,
    log: Callable[[str], None],
    cv: CrossValidation | None = None,
) -> tuple[TrainResult, dict[str, Any]]:
    """Write history.json and score the selected training on validation; when refitting,
    the model trained again on training + validation (refit_history.json). After
    cross-validation the validation split scores the model trained on the training part
    for the chosen count, and ``cross_validation`` holds what chose it."""
    (plan.run_dir / "history.json").write_text(json.dumps(result.summary(), indent=2) + "\n")
    data = plan.data
    metrics = {**val_metrics(result, data.val, data.normalizer), "best_epoch": result.best_epoch}
    if cv is not None:
        metrics["cross_validation"] = {
            k: v for k, v in cv.summary().items() if k not in ("pooled_curve_deg", "per_fold")
        }
    start_averaged, averaged = deployed_mirror(plan)
    if plan.init is not None:
        # How the handover scored them: the epochs as the file will run, the start
        # alone and, when that is its default, averaged (start_val_mae_forms).
        metrics["validation_mirror_averaged"] = {"start": start_averaged, "model": averaged}
    if result.best_epoch == 0:
        # Always said: the fine-tuning made the model worse on validation at every epoch.
        how = " (alone, nor averaged with its mirror image)" if start_averaged else ""
        where, best = (
            ("on validation", min(r.val_mae_deg for r in result.history))
            if cv is None
            else (f"out of fold ({len(cv.folds)} folds, pooled)", min(cv.curve))
        )
        print(
            f"sideslip-train: warning: no epoch of fine-tuning beat the starting model"
            f"{how} {where} (MAE {result.start_val_mae_deg:.4f} deg at the start, "
            f"{best:.4f} at best): kept its weights "
            "(try a lower --learning-rate, or more data)",
            file=sys.stderr,
        )
        metrics["kept_start_weights"] = True
    elif wants_refit(
        args.refit,
        pso=args.pso,
        val_given=bool(args.val),
        split=split,
        folds=args.folds,
        fixed_epochs=args.epochs is not None,
    ):
        # The epoch count chosen on validation, now on all the data before the test part.
        result, refit_history = refit(result, plan, log, init_state=plan.init_state())
        _toward_start(result, plan, args.interpolate, log)
        metrics["refit_epochs"] = len(refit_history)
        (plan.run_dir / "refit_history.json").write_text(
            json.dumps([asdict(r) for r in refit_history], indent=2) + "\n"
        )
    return result, metrics


def _toward_start(
    result: TrainResult, plan: TrainPlan, alpha: float, log: Callable[[str], None]
) -> None:
    """``--interpolate``: the fine-tuned weights moved back toward ``--init``'s (in
    place); nothing when the start's weights were kept or ``alpha`` is 1."""
    state = plan.init_state()
    if state is None or alpha >= 1.0 or result.best_epoch == 0:
        return
    interpolate_toward(result.model, state, alpha)
    log(f"weights: the start's + {alpha:g} x (fine-tuned - start's) (--interpolate)")


def _export(out: Path, result: TrainResult, meta: ModelMetadata) -> None:
    try:
        export_model(out, result.model, meta, force=True)
    except ArtifactError as err:
        raise _Stop(str(err), 1) from err


def _export_folds(
    run_dir: Path,
    cv: CrossValidation,
    metadata: Callable[[TrainResult, dict[str, Any]], ModelMetadata],
) -> None:
    """--folds: each fold's network (its best epoch on its own fold) as
    ``folds/fold-K.safetensors`` in the run folder, with no σ. They are K models trained
    on other parts of the same bags, so ``sideslip-merge`` can average them
    (docs/training.md, "Fine-tuning")."""
    folder = run_dir / "folds"
    folder.mkdir(exist_ok=True)
    for record, result in zip(cv.folds, cv.results, strict=True):
        metrics = {
            "fold": record.fold,
            "folds": len(cv.folds),
            "val_mae_deg": result.best_val_mae_deg,
            "best_epoch": result.best_epoch,
        }
        _export(folder / f"fold-{record.fold}.safetensors", result, metadata(result, metrics))


def _warn_if_still_improving(result: TrainResult, metrics: dict[str, Any]) -> None:
    if result.best_epoch >= len(result.history) and not result.stopped_early:
        # Always said, also with --quiet: the model was still improving when stopped.
        print(
            f"sideslip-train: warning: the best epoch was the last ({result.best_epoch} of "
            f"{len(result.history)}): the model was still improving; raise --max-epochs",
            file=sys.stderr,
        )
        metrics["still_improving"] = True
