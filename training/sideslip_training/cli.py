"""``sideslip-train``: bags → a trained, exported model (the PSO search is in
:mod:`.search`, ``sideslip-evaluate`` in :mod:`.evaluate_cli`).

The house CLI pattern: ``--help`` reads like a manual, progress bars on
anything long, ``--out`` never overwritten without ``--force``, and bad input (empty
data, a feature the bags lack, an existing output) is one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from sideslip_msgs_py.artifact import ARCHITECTURES, ArtifactError, ModelMetadata
from sideslip_msgs_py.features import FeatureError
from sideslip_msgs_py.model_inputs import INPUT_SETS, PRIORS, input_set
from sideslip_msgs_py.topic_map import TopicMap
from sideslip_msgs_py.vehicle_description import VehicleDescription

from . import __version__
from .cli_errors import EXIT_BAD_INPUT, CliError
from .config import DT_S, PROFILES, WINDOW_S, TrainProfile, profile
from .dataset import DatasetError, Run, data_digest, load_runs
from .export import export_model, load_model
from .init_model import InitError, check_fit, load_init
from .inputs import InputSpec
from .normalize import Normalizer
from .search import particle_threads, run_pso
from .splits import split_in_time, split_runs
from .trainer import EpochRecord, TrainConfig, TrainResult, pick_device, train_model
from .windows import WindowIndex

# --- sideslip-train --------------------------------------------------------------------


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
    p.add_argument("--batch-size", type=int, help="override the profile's batch size")
    p.add_argument("--swarm-size", type=int, help="override the profile's PSO swarm size")
    p.add_argument("--iterations", type=int, help="override the profile's PSO iterations")
    p.add_argument("--quiet", action="store_true")
    return p


def _check_out(args: argparse.Namespace) -> Path:
    """Refuse outputs that exist without --force; return the run folder (not made yet)."""
    out: Path = args.out
    if out.suffix != ".safetensors":
        raise CliError(f"--out {out}: must end in .safetensors")
    if out.exists() and not (args.force or args.resume):
        raise CliError(f"--out {out} exists; pass --force to replace it")
    run_dir = args.run_dir or out.with_suffix(".run")
    if args.resume:
        if not (run_dir / "pso_state.json").exists():
            raise CliError(f"--resume: no PSO state in {run_dir} (pso_state.json)")
    elif run_dir.exists() and not args.force:
        raise CliError(f"run folder {run_dir} exists; pass --force or --resume")
    elif run_dir.exists() and any(run_dir.iterdir()) and not (run_dir / "config.json").exists():
        # --force replaces a run folder, never an unrelated one (--run-dir . ...).
        raise CliError(f"run folder {run_dir} is not a sideslip-train run folder; not replacing it")
    return run_dir


def _make_run_dir(run_dir: Path, resume: bool) -> None:
    """Made only once the data has been accepted: a refused run leaves nothing behind."""
    if run_dir.exists() and not resume:
        shutil.rmtree(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)


def _check_features(runs: Sequence[Run], channels: Sequence[str]) -> None:
    for run in runs:
        for name in channels:
            column = np.asarray(getattr(run.samples, name))
            if not np.isfinite(column).any():
                raise CliError(f"feature {name} is missing from bag {run.path} (no finite value)")


def _split_mode(args: argparse.Namespace, runs: Sequence[Run]) -> str:
    """``bag`` or ``time``: ``auto`` takes bags apart when there are 3 or more."""
    if args.split != "auto":
        return str(args.split)
    return "bag" if len({r.bag for r in runs}) >= 3 else "time"


def _load(
    args: argparse.Namespace,
    prof: TrainProfile,
    spec: InputSpec,
    window: int,
    log,
    normalizer: Normalizer | None = None,
):
    """Runs for training, validation and test (the last may be empty), the statistics
    (``normalizer``, or fitted on the training runs) and the window indices. Fractions
    are of --data: test first, then validation."""
    topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
    load = {"channels": spec.channels, "step_s": spec.dt_s, "topic_map": topic_map}
    runs, report = load_runs(args.data, **load)
    log(str(report))
    mode = _split_mode(args, runs)
    val_fraction = prof.val_fraction if args.val_fraction is None else args.val_fraction
    test_runs: list[Run] = []
    if args.test:
        test_runs, test_report = load_runs(args.test, **load)
        log(f"test: {test_report}")
    elif args.test_fraction:
        if mode == "time":
            runs, test_runs = split_in_time(runs, args.test_fraction, "test")
        else:
            runs, test_runs = split_runs(runs, args.test_fraction, args.seed + 1)
        val_fraction = val_fraction / (1.0 - args.test_fraction)
    if args.val:
        train_runs = runs
        val_runs, val_report = load_runs(args.val, **load)
        log(f"validation: {val_report}")
    elif mode == "time":
        train_runs, val_runs = split_in_time(runs, val_fraction, "val")
    else:
        train_runs, val_runs = split_runs(runs, val_fraction, args.seed)
    checks = [(train_runs, val_runs, "--val")] if args.val else []
    checks += [([*train_runs, *val_runs], test_runs, "--test")] if args.test else []
    for ours, other, flag in checks:
        shared = {r.path for r in ours} & {r.path for r in other}
        if shared:
            raise CliError(f"{flag} shares {len(shared)} bag(s) with --data, e.g. {min(shared)}")
    log(
        f"split by {mode}: {len(train_runs)} training, {len(val_runs)} validation, "
        f"{len(test_runs)} test run(s)"
    )
    runs = [*train_runs, *val_runs]
    _check_features(runs, spec.channels)
    if spec.needs_observer:
        from . import observer

        assert spec.observer is not None
        log(f"UKF observer over {len(runs)} run(s) (cached in {observer.cache_dir()})")
        observer.precompute(
            runs,
            spec.observer,
            spec.observer_params_file,
            jobs=args.workers,
            progress=not args.quiet,
        )
    if normalizer is None:
        normalizer = Normalizer.fit(train_runs, spec, window)
    stride = prof.stride
    if args.stride is None:
        # Little data (a recording of minutes): every window, not every 10th; big data
        # (the fleet, over a million samples) keeps the profile's stride.
        stride = min(prof.stride, max(1, sum(len(r) for r in train_runs) // SAMPLES_PER_STRIDE))
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
    return runs, train_runs, val_runs, test_runs, normalizer, train, val, stride


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


def _val_metrics(result: TrainResult, val: WindowIndex, normalizer: Normalizer) -> dict[str, float]:
    """Validation errors in degrees against the exact (float64) ground truth."""
    import torch

    est = np.empty(len(val.ends))
    with torch.inference_mode():
        for start in range(0, len(val.ends), 8192):
            x, _ = val.batch(np.arange(start, min(start + 8192, len(val.ends))))
            est[start : start + x.shape[0]] = result.model(torch.from_numpy(x)).numpy()
    beta_hat = normalizer.invert_beta(est) + val.prior_rad[val.ends]
    err = np.degrees(beta_hat - val.beta_rad[val.ends])
    return {
        "val_mae_deg": float(np.mean(np.abs(err))),
        "val_rmse_deg": float(np.sqrt(np.mean(err**2))),
        "val_me_deg": float(np.mean(err)),
    }


SAMPLES_PER_STRIDE = 100_000
"""Without --stride, the stride is the profile's or one per this many training samples,
whichever is smaller."""


def _recorded_rate_hz(args: argparse.Namespace) -> float:
    """The rate the bags were recorded at (the median over the first five), so that a
    model runs at its car's own rate; within 1 % of the contract's 400 Hz, 400."""
    from sideslip_msgs_py.bag import read_bag
    from sideslip_msgs_py.resample import measured_step_s
    from sideslip_msgs_py.topic_map import read_mapped_bag

    from .dataset import find_bags

    topic_map = TopicMap.load(args.topic_map) if args.topic_map else None
    steps = []
    for path in find_bags(args.data)[:5]:
        try:
            samples = (
                read_bag(path).samples
                if topic_map is None
                else read_mapped_bag(path, topic_map).samples
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


def _window_steps(args: argparse.Namespace, step_s: float) -> int:
    """The window in samples: --window-steps, or --window-s at the model's rate (the
    horizon in seconds stays the same whatever the rate)."""
    if args.window_steps is not None:
        if args.window_steps < 2:
            raise CliError(f"--window-steps must be >= 2, got {args.window_steps}")
        return int(args.window_steps)
    window_s = WINDOW_S if args.window_s is None else args.window_s
    steps = round(window_s / step_s)
    if not (math.isfinite(window_s) and steps >= 2):
        raise CliError(f"--window-s {window_s:g} s is under two samples at {1 / step_s:g} Hz")
    return steps


def _test_metrics(model_path: Path, runs: Sequence[Run], log) -> dict[str, dict[str, float]]:
    """The exported model and the baselines on the test runs, pooled over their samples."""
    from .evaluate import evaluate_runs, model_label, pooled

    net, meta = load_model(model_path)
    traces = evaluate_runs(
        runs,
        [(model_label(meta), net, meta)],
        window_steps=meta.window_steps,
        dt_s=meta.dt_s,
    )
    out = {
        name: {"mae_deg": m.mae, "rmse_deg": m.rmse, "r2": m.r2, "samples": m.n}
        for name, m in pooled(traces).items()
    }
    log(
        "test (pooled over "
        + f"{len(runs)} run(s)): "
        + "; ".join(f"{n} MAE {v['mae_deg']:.4f} deg" for n, v in out.items())
    )
    return out


def train_main(argv: Sequence[str] | None = None) -> int:
    args = _train_parser().parse_args(argv)
    log = (lambda *_: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    started = time.perf_counter()
    try:
        prof = profile(args.profile)
        for name in ("max_epochs", "stride", "patience", "batch_size"):
            value = getattr(args, name)
            if value is not None:
                if value < 1:
                    flag = name.replace("_", "-")
                    raise CliError(f"{name} must be >= 1 (--{flag}), got {value}")
                prof = replace(prof, **{name: value})
        for name in ("swarm_size", "iterations"):
            value = getattr(args, name)
            if value is not None:
                if value < 1:
                    raise CliError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
                prof = replace(prof, pso=replace(prof.pso, **{name: value}))
        for name in ("val_fraction", "test_fraction"):
            value = getattr(args, name)
            if value is not None and not 0.0 <= value < 1.0:
                raise CliError(f"--{name.replace('_', '-')} must be in [0, 1), got {value}")
        if (args.val_fraction or 0.0) + args.test_fraction >= 1.0:
            raise CliError("--val-fraction + --test-fraction must leave data to train on")
        init = load_init(args.init) if args.init else None
        if init is None:
            if args.model is None:
                raise CliError("--model is required (or --init MODEL to fine-tune one)")
            features = input_set(args.features or "paper")
            args.prior = args.prior or "none"
            if args.rate_hz is None:
                args.rate_hz = _recorded_rate_hz(args)
                log(f"model rate {args.rate_hz:g} Hz: the bags' own (--rate-hz to choose)")
            hidden_units = (
                prof.default_hidden_units if args.hidden_units is None else args.hidden_units
            )
            layers = prof.layers
        else:
            m = init.meta
            given_window = (
                _window_steps(args, m.dt_s)
                if args.window_s is not None or args.window_steps is not None
                else None
            )
            check_fit(
                init,
                architecture=args.model,
                features=args.features,
                prior=args.prior,
                hidden_units=args.hidden_units,
                rate_hz=args.rate_hz,
                window_steps=given_window,
                pso=args.pso,
            )
            args.model, args.prior, args.rate_hz = m.architecture, m.prior, 1.0 / m.dt_s
            args.window_steps, args.window_s = m.window_steps, None
            features, hidden_units, layers = tuple(m.features), m.hidden_units, m.layers
        vehicle = VehicleDescription.load(args.vehicle) if args.vehicle else None
        if vehicle is None and init is not None and init.meta.vehicle is not None:
            vehicle = VehicleDescription.from_mapping(init.meta.vehicle)
        if args.workers < 1:
            raise CliError(f"--workers must be >= 1, got {args.workers}")
        base = TrainConfig(
            architecture=args.model,
            hidden_units=hidden_units,
            layers=layers,
            learning_rate=(
                prof.default_learning_rate if args.learning_rate is None else args.learning_rate
            ),
            max_epochs=prof.max_epochs,
            patience=prof.patience,
            batch_size=prof.batch_size,
            seed=args.seed,
            device=str(pick_device(args.device)),
        )
        if args.ray_address:
            from .parallel import import_ray

            import_ray()
        run_dir = _check_out(args)
        observer_file = str(args.observer_params) if args.observer_params else None
        if not (math.isfinite(args.rate_hz) and 50.0 <= args.rate_hz <= 1000.0):
            raise CliError(f"--rate-hz must be within 50-1000 Hz, got {args.rate_hz:g}")
        step_s = 1.0 / args.rate_hz
        window = _window_steps(args, step_s)
        observer = init.meta.observer if init is not None else None
        spec = InputSpec(features, args.prior, step_s, vehicle, observer, observer_file)
        keep = init.normalizer if init is not None and args.normalization == "keep" else None
        runs, train_runs, val_runs, test_runs, normalizer, train, val, stride = _load(
            args, prof, spec, window, log, normalizer=keep
        )
        dt_s = sample_period_s(runs)  # every bag now at step_s: a check, not a choice
    except (CliError, DatasetError, FeatureError, ImportError, ValueError, InitError) as err:
        print(f"sideslip-train: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT

    config = {
        "command": " ".join(["sideslip-train", *(argv if argv is not None else sys.argv[1:])]),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "profile": asdict(prof),
        "train_config": asdict(base),
        "features": list(features),
        "prior": args.prior,
        "observer": spec.observer,
        "train_bags": [r.name for r in train_runs],
        "val_bags": [r.name for r in val_runs],
        "test_bags": [r.name for r in test_runs],
        "split": _split_mode(args, train_runs + val_runs),
        "window_steps": window,
        "data_digest": data_digest(runs),
        "normalizer": normalizer.to_dict(),
        "sample_period_s": dt_s,
        "particle_threads": particle_threads(args) if args.pso else None,
        "sideslip_training": __version__,
    }
    config_path = run_dir / "config.json"
    if args.resume:
        # A resumed PSO must continue the same run: same data, split, statistics, model.
        old = json.loads(config_path.read_text())
        keys = (
            "data_digest",
            "features",
            "prior",
            "observer",
            "train_bags",
            "val_bags",
            "normalizer",
            "particle_threads",
        )
        changed = [
            k
            for k in (*keys, "train_config")
            if old.get(k) != json.loads(json.dumps(config[k], default=str))
        ]
        if changed:
            print(
                f"sideslip-train: error: --resume: {run_dir} was started with other "
                f"{', '.join(changed)}; resume with the original command",
                file=sys.stderr,
            )
            return EXIT_BAD_INPUT
    else:
        _make_run_dir(run_dir, resume=False)
        config_path.write_text(json.dumps(config, indent=2, default=str) + "\n")

    pso_info = None
    if args.pso:
        from .pso import PsoError

        try:
            result, pso_info = run_pso(args, prof, base, train, val, normalizer, run_dir, log)
        except PsoError as err:  # e.g. a damaged or foreign pso_state.json on --resume
            print(f"sideslip-train: error: {err}", file=sys.stderr)
            return EXIT_BAD_INPUT
    else:
        try:
            state = init.net.state_dict() if init is not None else None
            result = _train_one(base, train, val, normalizer, args.quiet, init_state=state)
        except ValueError as err:  # diverged: no epoch to export
            print(f"sideslip-train: error: {err}", file=sys.stderr)
            return 1
    (run_dir / "history.json").write_text(json.dumps(result.summary(), indent=2) + "\n")

    metrics = {**_val_metrics(result, val, normalizer), "best_epoch": result.best_epoch}
    refit = args.refit == "yes" or (
        args.refit == "auto" and not args.pso and not args.val and config["split"] == "time"
    )
    if refit and not args.pso:
        # The epoch count chosen on validation, now on all the data before the test part.
        both = WindowIndex.build([*train_runs, *val_runs], spec, normalizer, window, stride)
        log(
            f"refit on training + validation ({len(both.ends)} windows), {result.best_epoch} epochs"
        )
        selection = result
        result = train_model(
            replace(base, max_epochs=result.best_epoch),
            both,
            val,
            normalizer,
            init_state=init.net.state_dict() if init is not None else None,
            keep_last=True,
        )
        result.stopped_early = selection.stopped_early
        result.history, selection_history = selection.history, result.history
        metrics["refit_epochs"] = len(selection_history)
        (run_dir / "refit_history.json").write_text(
            json.dumps([asdict(r) for r in selection_history], indent=2) + "\n"
        )
    meta = ModelMetadata(
        architecture=args.model,
        hidden_units=result.model.config.hidden_units,
        layers=result.model.config.layers,
        features=tuple(features),
        window_steps=window,
        dt_s=dt_s,
        feature_mean=tuple(float(v) for v in normalizer.mean),
        feature_std=tuple(float(v) for v in normalizer.std),
        beta_mean=float(normalizer.beta_mean),
        beta_std=float(normalizer.beta_std),
        training_data_digest=config["data_digest"],
        metrics=metrics,
        pso=pso_info,
        prior=spec.prior,
        vehicle=vehicle.to_dict() if vehicle is not None else None,
        observer=dict(spec.observer) if spec.observer is not None else None,
        created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        provenance={
            **(
                {
                    "init": init.path.name,
                    "init_data": init.meta.training_data_digest,
                    "normalization": args.normalization,
                }
                if init is not None
                else {}
            ),
            "command": config["command"],
            "profile": prof.name,
            "device": result.device,
            "train_bags": len(train_runs),
            "val_bags": len(val_runs),
            "wall_s": round(time.perf_counter() - started, 1),
            "sideslip_training": __version__,
        },
    )
    try:
        export_model(args.out, result.model, meta, force=True)
    except ArtifactError as err:
        print(f"sideslip-train: error: {err}", file=sys.stderr)
        return 1
    if result.best_epoch >= len(result.history) and not result.stopped_early:
        # Always said, also with --quiet: the model was still improving when stopped.
        print(
            f"sideslip-train: warning: the best epoch was the last ({result.best_epoch} of "
            f"{len(result.history)}): the model was still improving; raise --max-epochs",
            file=sys.stderr,
        )
        metrics["still_improving"] = True
    if test_runs:
        metrics["test"] = _test_metrics(args.out, test_runs, log)
    total = time.perf_counter() - started
    summary = {**metrics, "wall_s": total, "out": str(args.out), "run_dir": str(run_dir)}
    (run_dir / "metrics.json").write_text(json.dumps(summary, indent=2) + "\n")
    log(
        f"wrote {args.out}: validation MAE {metrics['val_mae_deg']:.4f} deg, "
        f"RMSE {metrics['val_rmse_deg']:.4f} deg, {total:.0f} s"
    )
    return 0


def _train_one(
    cfg: TrainConfig,
    train: WindowIndex,
    val: WindowIndex,
    normalizer: Normalizer,
    quiet: bool,
    init_state: Mapping[str, Any] | None = None,
) -> TrainResult:
    from tqdm import tqdm

    bar = tqdm(total=cfg.max_epochs, unit="epoch", disable=quiet, file=sys.stderr)

    def on_epoch(r: EpochRecord) -> None:
        bar.set_postfix(val_mae_deg=f"{r.val_mae_deg:.4f}", win_per_s=f"{r.windows_per_s:.0f}")
        bar.update()

    try:
        return train_model(cfg, train, val, normalizer, on_epoch=on_epoch, init_state=init_state)
    finally:
        bar.close()
