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
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from sideslip_msgs_py.artifact import ARCHITECTURES, ArtifactError, ModelMetadata
from sideslip_msgs_py.features import FeatureError
from sideslip_msgs_py.model_inputs import INPUT_SETS, PRIORS

from .cli_errors import EXIT_BAD_INPUT, CliError
from .config import PROFILES
from .dataset import DatasetError
from .export import export_model
from .final_model import model_metadata, refit, wants_refit
from .init_model import InitError
from .inputs import add_car_argument
from .run_folder import start_run_folder
from .search import run_pso
from .train_intervals import INTERVAL_POLICIES, calibrate_selection, interval_mode
from .train_metrics import pooled_test_metrics, val_metrics
from .train_plan import TrainPlan, plan_training, run_config
from .trainer import EpochRecord, TrainResult, train_model


def _train_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-train",
        description=(
            "Train an LSTM or BiLSTM sideslip estimator on rosbag2 bags (ours or your "
            "car's, recorded with ros2 bag record or sideslip-record), optionally with "
            "PSO over learning rate and hidden units, and export it as one .safetensors "
            "file that the estimator node's pso_lstm back-end loads."
        ),
        epilog=(
            "Bags are split into training, validation (and, with --test-fraction, test) by "
            "bag, or for one long recording in time (--split; never by window); the z-score "
            "statistics come from the training part only. The run folder (default: OUT "
            "without suffix + '.run') holds config.json, history.json, metrics.json (with "
            "the test part's figures), the PSO history and state (pso_history.json, "
            "pso_state.json), plots and each particle's model; --resume continues an "
            "interrupted PSO from it. Profiles: "
            + "; ".join(
                f"{p.name}: {p.max_epochs} epochs, patience {p.patience}, batch "
                f"{p.batch_size}, stride {p.stride}, {p.default_hidden_units} units and "
                f"learning rate {p.default_learning_rate:g} without PSO, validation "
                f"{p.val_fraction:g}, PSO {p.pso.swarm_size} particles x "
                f"{p.pso.iterations} iterations"
                for p in PROFILES.values()
            )
            + " (each can be overridden by its option)."
        ),
    )
    p.add_argument(
        "--data", nargs="+", required=True, metavar="DIR", help="bags or folders of bags"
    )
    p.add_argument(
        "--val",
        nargs="+",
        metavar="DIR",
        help="validation bags (e.g. other cars than --data's, so that selection measures "
        "generalisation); default: a fraction of --data's bags",
    )
    p.add_argument(
        "--test",
        nargs="+",
        metavar="DIR",
        help="test bags, scored once after training (model and baselines, in metrics.json)",
    )
    p.add_argument(
        "--split",
        choices=["auto", "bag", "time"],
        default="auto",
        help="how --data is split: by bag (whole bags to each side), or in time (the last "
        "fractions of every bag: for one long recording); auto: by bag from 3 bags on",
    )
    p.add_argument(
        "--val-fraction",
        type=float,
        help="share of --data for validation (default: the profile's, 0.2)",
    )
    p.add_argument(
        "--test-fraction",
        type=float,
        default=0.0,
        help="share of --data held out as test (in time: each bag's last part), scored "
        "once after training",
    )
    p.add_argument(
        "--refit",
        choices=["auto", "yes", "no"],
        default="auto",
        help="after early stopping chose the epoch count on validation, train again on "
        "training + validation for that many epochs and export that model; auto: when the "
        "split is in time (the validation part is then the stretch before the test)",
    )
    p.add_argument(
        "--intervals",
        choices=list(INTERVAL_POLICIES),
        default="auto",
        help="the per-sample σ the model publishes, calibrated on the validation runs "
        "with the model early stopping chose (before any refit): scale keeps the --init "
        "model's σ terms and fits their scale; fit fits terms and scale on halves of the "
        "validation bags; auto (default): scale when fine-tuning a model with σ terms, "
        "else fit with two or more validation bags, else none; no: none (the constant "
        "validation RMSE²)",
    )
    p.add_argument(
        "--window-s",
        type=float,
        help="window length in seconds (default 0.25, the paper's): the same horizon at "
        "every --rate-hz",
    )
    p.add_argument("--window-steps", type=int, help="window length in samples instead")
    p.add_argument(
        "--model",
        choices=list(ARCHITECTURES),
        help="architecture (required unless --init gives it)",
    )
    p.add_argument(
        "--init",
        metavar="MODEL",
        help="fine-tune: start from this model's weights (a .safetensors or a shipped name); "
        "its architecture, size, inputs, prior, window and rate are used, and options that "
        "contradict them are refused",
    )
    p.add_argument(
        "--normalization",
        choices=["keep", "refit"],
        default="keep",
        help="with --init: keep the model's z-score statistics (default; the first epoch "
        "starts from the model's answer) or refit them on the new data",
    )
    p.add_argument("--pso", action="store_true", help="tune learning rate and hidden units by PSO")
    p.add_argument(
        "--features",
        choices=list(INPUT_SETS),
        help="model inputs (default: paper; with --init: the model's): paper (X_v, Y_v, "
        "X_a, Y_a, yaw rate, STL) and measurable (no Y_v) as measured; paper_kinematic "
        "(kinematic inputs only, no steering) and "
        "measurable_invariant (accelerations in g, road-wheel and understeer angles, the "
        "car's mass, wheelbase, weight split and CG height as inputs); measurable_observer "
        "(measurable_invariant plus the UKF observer's β̂ and road μ̂)",
    )
    p.add_argument(
        "--prior",
        choices=list(PRIORS),
        help="physics estimate the network corrects (β̂ = prior + network; default none, "
        "with --init the model's): none, "
        "kinematic_window (the window's dead-reckoned atan2(Y_v, X_v); needs Y_v), or ukf "
        "(the estimator's UKF with the car's nominal parameters; measurable channels)",
    )
    p.add_argument(
        "--observer-params",
        type=Path,
        metavar="UKF.yaml",
        help="the car's ukf params file (python -m sideslip_sim.ukf_params) for bags that "
        "record no car, when the inputs or the prior read the UKF observer",
    )
    p.add_argument(
        "--vehicle",
        type=Path,
        help="nominal parameters (YAML) of the car of bags that record none, for inputs "
        "that read the vehicle (simulated bags record theirs)",
    )
    add_car_argument(p)
    p.add_argument("--profile", default="quick", choices=list(PROFILES))
    p.add_argument(
        "--rate-hz",
        type=float,
        help="the rate the model runs at [Hz] (default: the bags' own, with --init the "
        "model's): bags at "
        "another rate are resampled to it (low-pass filtered first when downsampling), "
        "bags outside 50-1000 Hz refused; the report says which",
    )
    p.add_argument("--out", required=True, type=Path, metavar="FILE.safetensors")
    p.add_argument(
        "--topic-map",
        type=Path,
        metavar="FILE",
        help="read bags recorded with other topics/types through this map (YAML: topic and "
        "field of each channel and of the reference β or velocity; docs/topic-maps.md)",
    )
    p.add_argument("--force", action="store_true", help="replace --out and its run folder")
    p.add_argument("--run-dir", type=Path, help="run folder (default: OUT.run)")
    p.add_argument("--resume", action="store_true", help="continue the PSO in the run folder")
    p.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    p.add_argument("--workers", type=int, default=1, help="parallel PSO particles (processes)")
    p.add_argument(
        "--ray-address", help="run PSO particles on this Ray cluster ('auto', ray://...)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--hidden-units", type=int, help="without --pso (default: the profile's)")
    p.add_argument("--learning-rate", type=float, help="without --pso (default: the profile's)")
    p.add_argument("--max-epochs", type=int, help="override the profile's epoch limit")
    p.add_argument("--stride", type=int, help="override the profile's window stride [samples]")
    p.add_argument("--patience", type=int, help="override the profile's early-stopping patience")
    p.add_argument(
        "--average-weights",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="score and keep a moving average of the weights over about the last epoch "
        "instead of the last step's (default on; docs/training.md, 'Small data')",
    )
    p.add_argument(
        "--mirror",
        choices=["auto", "yes", "no"],
        default="auto",
        help="also train on every training run mirrored left-right (steering, lateral "
        "velocity and acceleration, yaw rate and β negated): a car is symmetric, so this "
        "doubles the data; validation and test stay as recorded. auto (default): when the "
        "training part is small (under 1 M samples with the quick profile, as for the "
        "stride; docs/training.md, 'Small data')",
    )
    p.add_argument("--batch-size", type=int, help="override the profile's batch size")
    p.add_argument("--swarm-size", type=int, help="override the profile's PSO swarm size")
    p.add_argument("--iterations", type=int, help="override the profile's PSO iterations")
    p.add_argument("--quiet", action="store_true")
    return p


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
    args = _train_parser().parse_args(argv)
    log = (lambda *_: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    started = time.perf_counter()
    try:
        plan = plan_training(args, log)
        intervals = interval_mode(args.intervals, plan)
    except (CliError, DatasetError, FeatureError, ImportError, ValueError, InitError) as err:
        return _error(err, EXIT_BAD_INPUT)
    command = " ".join(["sideslip-train", *(argv if argv is not None else sys.argv[1:])])
    config = run_config(args, command, plan)
    try:
        start_run_folder(plan.run_dir, config, resume=args.resume)
    except CliError as err:  # --resume of a run started otherwise
        return _error(err, EXIT_BAD_INPUT)
    try:
        result, pso_info = _train(args, plan, log)

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
            intervals, plan, result.model, metadata(result, {}), args.seed, log
        )
        result, metrics = _validate_and_refit(args, plan, config["split"], result, log)
        if calibration is not None:
            metrics["interval_calibration"] = calibration
        meta = replace(metadata(result, metrics), uncertainty=uncertainty)
        _export(args.out, result, meta)
    except _Stop as stop:
        return _error(stop, stop.exit_code)
    _warn_if_still_improving(result, metrics)
    if plan.data.test_runs:
        metrics["test"] = pooled_test_metrics(args.out, plan.data.test_runs, log, plan.spec)
    total = time.perf_counter() - started
    summary = {**metrics, "wall_s": total, "out": str(args.out), "run_dir": str(plan.run_dir)}
    (plan.run_dir / "metrics.json").write_text(json.dumps(summary, indent=2) + "\n")
    log(
        f"wrote {args.out}: validation MAE {metrics['val_mae_deg']:.4f} deg, "
        f"RMSE {metrics['val_rmse_deg']:.4f} deg, {total:.0f} s"
    )
    return 0


def _train(
    args: argparse.Namespace, plan: TrainPlan, log: Callable[[str], None]
) -> tuple[TrainResult, dict[str, Any] | None]:
    """The selected training and the PSO record: PSO's best particle, or one training
    (from --init's weights when fine-tuning)."""
    data = plan.data
    if args.pso:
        from .pso import PsoError

        try:
            return run_pso(
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
    try:
        result = _train_one(plan, args.quiet)
    except ValueError as err:  # diverged: no epoch to export
        raise _Stop(str(err), 1) from err
    return result, None


def _train_one(plan: TrainPlan, quiet: bool) -> TrainResult:
    """One training with a progress bar over the epochs (on stderr, off with --quiet)."""
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
        )
    finally:
        bar.close()


def _validate_and_refit(
    args: argparse.Namespace,
    plan: TrainPlan,
    split: str,
    result: TrainResult,
    log: Callable[[str], None],
) -> tuple[TrainResult, dict[str, Any]]:
    """Write history.json and score the selected training on validation; when refitting,
    the model trained again on training + validation (refit_history.json)."""
    (plan.run_dir / "history.json").write_text(json.dumps(result.summary(), indent=2) + "\n")
    data = plan.data
    metrics = {**val_metrics(result, data.val, data.normalizer), "best_epoch": result.best_epoch}
    if result.best_epoch == 0:
        # Always said: the fine-tuning made the model worse on validation at every epoch.
        print(
            f"sideslip-train: warning: no epoch of fine-tuning beat the starting model on "
            f"validation (MAE {result.start_val_mae_deg:.4f} deg at the start, "
            f"{min(r.val_mae_deg for r in result.history):.4f} at best): kept its weights "
            "(try a lower --learning-rate, or more data)",
            file=sys.stderr,
        )
        metrics["kept_start_weights"] = True
    elif wants_refit(args.refit, pso=args.pso, val_given=bool(args.val), split=split):
        # The epoch count chosen on validation, now on all the data before the test part.
        result, refit_history = refit(result, plan, log, init_state=plan.init_state())
        metrics["refit_epochs"] = len(refit_history)
        (plan.run_dir / "refit_history.json").write_text(
            json.dumps([asdict(r) for r in refit_history], indent=2) + "\n"
        )
    return result, metrics


def _export(out: Path, result: TrainResult, meta: ModelMetadata) -> None:
    try:
        export_model(out, result.model, meta, force=True)
    except ArtifactError as err:
        raise _Stop(str(err), 1) from err


def _warn_if_still_improving(result: TrainResult, metrics: dict[str, Any]) -> None:
    if result.best_epoch >= len(result.history) and not result.stopped_early:
        # Always said, also with --quiet: the model was still improving when stopped.
        print(
            f"sideslip-train: warning: the best epoch was the last ({result.best_epoch} of "
            f"{len(result.history)}): the model was still improving; raise --max-epochs",
            file=sys.stderr,
        )
        metrics["still_improving"] = True
