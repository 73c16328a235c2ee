"""``sideslip-train`` and ``sideslip-evaluate``: bags → trained, evaluated, exported models.

Both follow the house CLI pattern: ``--help`` reads like a manual, progress bars on
anything long, ``--out`` never overwritten without ``--force``, and bad input (empty
data, a feature the bags lack, an existing output) is one line on stderr and exit 2.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from sideslip_msgs_py.artifact import ArtifactError, ModelMetadata
from sideslip_msgs_py.features import FeatureError, feature_set

from . import __version__
from .config import DT_S, WINDOW_STEPS, TrainProfile, profile
from .dataset import DatasetError, Run, data_digest, load_runs, split_runs
from .export import export_model, load_model
from .normalize import Normalizer
from .trainer import EpochRecord, TrainConfig, TrainResult, train_model
from .windows import WindowIndex

EXIT_BAD_INPUT = 2


class CliError(Exception):
    """Bad input a user can fix: printed as one line, exit code 2."""


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
            "Bags are split into training and validation by bag (never by window); the "
            "z-score statistics come from the training bags only. The run folder (default: "
            "OUT without suffix + '.run') holds config.json, history.json, metrics.json, "
            "the PSO history and state (pso_history.json, pso_state.json), plots and each "
            "particle's model; --resume continues an interrupted PSO from it."
        ),
    )
    p.add_argument(
        "--data", nargs="+", required=True, metavar="DIR", help="bags or folders of bags"
    )
    p.add_argument("--model", choices=["lstm", "bilstm"], required=True)
    p.add_argument("--pso", action="store_true", help="tune learning rate and hidden units by PSO")
    p.add_argument("--features", default="paper", choices=["paper", "measurable"])
    p.add_argument("--profile", default="quick", choices=["quick", "paper"])
    p.add_argument("--out", required=True, type=Path, metavar="FILE.safetensors")
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
    p.add_argument("--quiet", action="store_true")
    return p


@dataclass(frozen=True)
class ParticleContext:
    """What every PSO particle's training needs (pickled once per worker / Ray object)."""

    train: WindowIndex
    val: WindowIndex
    normalizer: Normalizer
    base: TrainConfig
    particle_dir: str
    threads: int


def particle_path(particle_dir: str, params: dict[str, Any]) -> Path:
    """Where a particle's weights go (a torch state dict: internal to the run folder)."""
    lr = 10.0 ** float(params["log10_learning_rate"])
    return Path(particle_dir) / f"lr{lr:.4e}_h{int(params['hidden_units'])}.pt"


def particle_fitness(params: dict[str, Any], ctx: ParticleContext) -> float:
    """Train one particle's network; its fitness is the validation MAE [deg] (Sec. 2.2)."""
    import torch

    torch.set_num_threads(ctx.threads)
    cfg = replace(
        ctx.base,
        learning_rate=10.0 ** float(params["log10_learning_rate"]),
        hidden_units=int(params["hidden_units"]),
    )
    result = train_model(cfg, ctx.train, ctx.val, ctx.normalizer)
    # Kept so the final model is the best particle's weights as PSO scored them.
    torch.save(result.model.state_dict(), particle_path(ctx.particle_dir, params))
    return result.best_val_mae_deg


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
    return run_dir


def _make_run_dir(run_dir: Path, resume: bool) -> None:
    """Made only once the data has been accepted: a refused run leaves nothing behind."""
    if run_dir.exists() and not resume:
        shutil.rmtree(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)


def _check_features(runs: Sequence[Run], features: Sequence[str]) -> None:
    for run in runs:
        for name in features:
            column = np.asarray(getattr(run.samples, name))
            if not np.isfinite(column).any():
                raise CliError(f"feature {name} is missing from bag {run.path} (no finite value)")


def _load(args: argparse.Namespace, prof: TrainProfile, features: Sequence[str], log):
    runs, report = load_runs(args.data)
    log(str(report))
    _check_features(runs, features)
    train_runs, val_runs = split_runs(runs, prof.val_fraction, args.seed)
    normalizer = Normalizer.fit(train_runs, tuple(features))
    train = WindowIndex.build(train_runs, tuple(features), normalizer, WINDOW_STEPS, prof.stride)
    val = WindowIndex.build(val_runs, tuple(features), normalizer, WINDOW_STEPS, prof.stride)
    log(
        f"{len(train_runs)} training bag(s), {len(train.ends)} windows; "
        f"{len(val_runs)} validation bag(s), {len(val.ends)} windows (stride {prof.stride})"
    )
    return runs, train_runs, val_runs, normalizer, train, val


def _val_metrics(result: TrainResult, val: WindowIndex, normalizer: Normalizer) -> dict[str, float]:
    """Validation errors in degrees against the exact (float64) ground truth."""
    import torch

    est = np.empty(len(val.ends))
    with torch.inference_mode():
        for start in range(0, len(val.ends), 8192):
            x, _ = val.batch(np.arange(start, min(start + 8192, len(val.ends))))
            est[start : start + x.shape[0]] = result.model(torch.from_numpy(x)).numpy()
    err = np.degrees(normalizer.invert_beta(est) - val.beta_rad[val.ends])
    return {
        "val_mae_deg": float(np.mean(np.abs(err))),
        "val_rmse_deg": float(np.sqrt(np.mean(err**2))),
        "val_me_deg": float(np.mean(err)),
    }


def train_main(argv: Sequence[str] | None = None) -> int:
    args = _train_parser().parse_args(argv)
    log = (lambda *_: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    started = time.perf_counter()
    try:
        prof = profile(args.profile)
        if args.max_epochs is not None:
            prof = replace(prof, max_epochs=args.max_epochs)
        features = feature_set(args.features)
        if args.workers < 1:
            raise CliError(f"--workers must be >= 1, got {args.workers}")
        run_dir = _check_out(args)
        runs, train_runs, val_runs, normalizer, train, val = _load(args, prof, features, log)
        _make_run_dir(run_dir, args.resume)
    except (CliError, DatasetError, FeatureError, ValueError) as err:
        print(f"sideslip-train: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT

    base = TrainConfig(
        architecture=args.model,
        hidden_units=args.hidden_units or prof.default_hidden_units,
        layers=prof.layers,
        learning_rate=args.learning_rate or prof.default_learning_rate,
        max_epochs=prof.max_epochs,
        patience=prof.patience,
        batch_size=prof.batch_size,
        seed=args.seed,
        device=args.device,
    )
    config = {
        "command": " ".join(["sideslip-train", *(argv if argv is not None else sys.argv[1:])]),
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "profile": asdict(prof),
        "train_config": asdict(base),
        "features": list(features),
        "train_bags": [r.name for r in train_runs],
        "val_bags": [r.name for r in val_runs],
        "data_digest": data_digest(runs),
        "normalizer": normalizer.to_dict(),
        "sideslip_training": __version__,
    }
    (run_dir / "config.json").write_text(json.dumps(config, indent=2, default=str) + "\n")

    pso_info = None
    if args.pso:
        result, pso_info = _run_pso(args, prof, base, train, val, normalizer, run_dir, log)
    else:
        result = _train_one(base, train, val, normalizer, args.quiet)
    (run_dir / "history.json").write_text(json.dumps(result.summary(), indent=2) + "\n")

    metrics = {**_val_metrics(result, val, normalizer), "best_epoch": result.best_epoch}
    meta = ModelMetadata(
        architecture=args.model,
        hidden_units=result.model.config.hidden_units,
        layers=result.model.config.layers,
        features=tuple(features),
        window_steps=WINDOW_STEPS,
        dt_s=DT_S,
        feature_mean=tuple(float(v) for v in normalizer.mean),
        feature_std=tuple(float(v) for v in normalizer.std),
        beta_mean=float(normalizer.beta_mean),
        beta_std=float(normalizer.beta_std),
        training_data_digest=config["data_digest"],
        metrics=metrics,
        pso=pso_info,
        created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        provenance={
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
    total = time.perf_counter() - started
    summary = {**metrics, "wall_s": total, "out": str(args.out), "run_dir": str(run_dir)}
    (run_dir / "metrics.json").write_text(json.dumps(summary, indent=2) + "\n")
    log(
        f"wrote {args.out}: validation MAE {metrics['val_mae_deg']:.4f} deg, "
        f"RMSE {metrics['val_rmse_deg']:.4f} deg, {total:.0f} s"
    )
    return 0


def _train_one(
    cfg: TrainConfig, train: WindowIndex, val: WindowIndex, normalizer: Normalizer, quiet: bool
) -> TrainResult:
    from tqdm import tqdm

    bar = tqdm(total=cfg.max_epochs, unit="epoch", disable=quiet, file=sys.stderr)

    def on_epoch(r: EpochRecord) -> None:
        bar.set_postfix(val_mae_deg=f"{r.val_mae_deg:.4f}", win_per_s=f"{r.windows_per_s:.0f}")
        bar.update()

    try:
        return train_model(cfg, train, val, normalizer, on_epoch=on_epoch)
    finally:
        bar.close()


def _run_pso(args, prof, base, train, val, normalizer, run_dir: Path, log):
    import torch
    from tqdm import tqdm

    from .parallel import make_evaluator
    from .pso import PsoState, hyperparameter_space, optimize
    from .pso_plot import plot_convergence

    settings = replace(prof.pso, seed=args.seed)
    space = hyperparameter_space(settings)
    particle_dir = run_dir / "particles"
    particle_dir.mkdir(exist_ok=True)
    cores = os.cpu_count() or 1
    ctx = ParticleContext(
        train, val, normalizer, base, str(particle_dir), max(1, cores // args.workers)
    )
    state_path = run_dir / "pso_state.json"
    state = PsoState.load(state_path) if args.resume else None
    evaluator = make_evaluator(
        particle_fitness, ctx, workers=args.workers, ray_address=args.ray_address
    )
    bar = tqdm(
        total=settings.iterations + 1,
        unit="iteration",
        disable=args.quiet,
        file=sys.stderr,
        desc=f"PSO ({settings.swarm_size} particles)",
    )

    def on_iteration(s: PsoState) -> None:
        s.save(state_path)  # atomic: an interruption never leaves half a state
        (run_dir / "pso_history.json").write_text(s.history.to_json())
        plot_convergence(s.history, run_dir / "pso_convergence.png")
        bar.n = s.iteration + 1
        bar.set_postfix(best_mae_deg=f"{s.global_best_fitness:.4f}")
        bar.refresh()

    try:
        result = optimize(evaluator, space, settings, state=state, on_iteration=on_iteration)
    finally:
        bar.close()
        close = getattr(evaluator, "close", None)
        if close is not None:
            close()
    best = result.best_params
    log(f"PSO best: {best} -> validation MAE {result.best_fitness:.4f} deg")
    # The best particle's trained weights, exactly as PSO scored them (no retraining).
    from .model import ModelConfig, SideslipNet

    net = SideslipNet(
        ModelConfig(
            base.architecture, len(normalizer.features), int(best["hidden_units"]), base.layers
        )
    )
    net.load_state_dict(torch.load(particle_path(str(particle_dir), best), weights_only=True))
    net.eval()
    cfg = replace(
        base,
        learning_rate=10.0 ** float(best["log10_learning_rate"]),
        hidden_units=int(best["hidden_units"]),
    )
    tr = TrainResult(
        model=net, best_epoch=0, best_val_mae_deg=result.best_fitness, device=base.device
    )
    info = {
        "best_learning_rate": cfg.learning_rate,
        "best_hidden_units": cfg.hidden_units,
        "best_val_mae_deg": result.best_fitness,
        "iterations": settings.iterations,
        "swarm_size": settings.swarm_size,
        "trainings": result.evaluations,
        "settings": asdict(settings),
        "history_file": "pso_history.json",
    }
    return tr, info


# --- sideslip-evaluate -----------------------------------------------------------------


def _evaluate_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-evaluate",
        description=(
            "Score exported models (and the kinematic baseline atan2(Y_v, X_v), raw and "
            "smoothed) on bags with ground truth: MAE, ME, RMSE, R² in degrees per bag "
            "(scenario) in the paper's Table 5/6 layout, β traces and error PDFs."
        ),
    )
    p.add_argument("--model", nargs="+", required=True, type=Path, metavar="FILE")
    p.add_argument("--data", nargs="+", required=True, metavar="DIR")
    p.add_argument("--out", type=Path, help="report folder: table.md, table.csv, figures")
    p.add_argument("--force", action="store_true", help="write into an existing --out")
    p.add_argument("--smoothing", type=int, default=20, help="smoothed baseline: samples averaged")
    p.add_argument("--title", default="", help="heading of the markdown table")
    return p


def evaluate_main(argv: Sequence[str] | None = None) -> int:
    from .evaluate import (
        evaluate_runs,
        model_label,
        plot_error_pdfs,
        plot_traces,
        table_csv,
        table_markdown,
    )

    args = _evaluate_parser().parse_args(argv)
    try:
        if (
            args.out is not None
            and args.out.exists()
            and any(args.out.iterdir())
            and not args.force
        ):
            raise CliError(f"--out {args.out} is not empty; pass --force")
        if args.smoothing < 1:
            raise CliError(f"--smoothing must be >= 1, got {args.smoothing}")
        models = []
        for path in args.model:
            net, meta = load_model(path)
            models.append((model_label(meta), net, meta))
        names = [m[0] for m in models]
        if len(set(names)) != len(names):  # two LSTMs: tell them apart by file
            stems = [p.stem for p in args.model]
            tags = stems if len(set(stems)) == len(stems) else [p.parent.name for p in args.model]
            models = [
                (f"{n} ({tag})", net, meta)
                for (n, net, meta), tag in zip(models, tags, strict=True)
            ]
        windows = {meta.window_steps for _, _, meta in models}
        if len(windows) != 1:
            raise CliError(f"models have different window lengths: {sorted(windows)}")
        runs, report = load_runs(args.data)
        print(str(report), file=sys.stderr)
    except (CliError, ArtifactError, DatasetError, OSError) as err:
        print(f"sideslip-evaluate: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    traces = evaluate_runs(runs, models, window_steps=windows.pop(), smoothing_steps=args.smoothing)
    md = table_markdown(traces, args.title)
    print(md)
    if args.out is not None:
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / "table.md").write_text(md)
        (args.out / "table.csv").write_text(table_csv(traces))
        plot_traces(traces, args.out)
        plot_error_pdfs(traces, args.out)
        summary = {
            "models": [str(p) for p in args.model],
            "data": args.data,
            "smoothing_steps": args.smoothing,
            "results": [
                {"scenario": t.scenario, "estimator": t.estimator, **asdict(t.metrics)}
                for t in traces
            ],
        }
        (args.out / "metrics.json").write_text(
            json.dumps(
                summary,
                indent=2,
                default=lambda v: None if isinstance(v, float) and math.isnan(v) else v,
            )
            + "\n"
        )
    return 0
