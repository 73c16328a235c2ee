"""The PSO search of ``sideslip-train --pso``: one particle = one training, its fitness
the validation MAE (the paper's Sec. 2.2); the best particle's weights, exactly as PSO
scored them, become the model. Worker processes (and Ray tasks) import this module to
run a particle, not the CLI.
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

from .config import TrainProfile
from .normalize import Normalizer
from .trainer import EpochRecord, TrainConfig, TrainResult, train_model
from .windows import WindowIndex


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
    """Where a particle's weights go (internal to the run folder).

    Named by the exact parameters (full float precision): particles clamped onto the
    same bound share one file, written atomically; the file also holds the fitness and
    the training summary of the weights it holds.
    """
    lr = float(params["log10_learning_rate"]).hex()
    return Path(particle_dir) / f"lr{lr}_h{int(params['hidden_units'])}.pt"


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
    path = particle_path(ctx.particle_dir, params)
    tmp = path.with_suffix(f".{os.getpid()}.tmp")
    torch.save(
        {
            "state_dict": result.model.state_dict(),
            "fitness": result.best_val_mae_deg,
            "summary": {k: v for k, v in result.summary().items()},
        },
        tmp,
    )
    os.replace(tmp, path)
    return result.best_val_mae_deg


def particle_threads(args: argparse.Namespace) -> int:
    """Torch threads per particle: a Ray task reserves one CPU; a local pool shares the
    cores. Recorded in config.json: results depend on it (float summation order)."""
    if args.ray_address:
        return 1
    return max(1, (os.cpu_count() or 1) // args.workers)


def run_pso(
    args: argparse.Namespace,
    prof: TrainProfile,
    base: TrainConfig,
    train: WindowIndex,
    val: WindowIndex,
    normalizer: Normalizer,
    run_dir: Path,
    log,
) -> tuple[TrainResult, dict[str, Any]]:
    """Search (log10 learning rate, hidden units) by PSO; the best particle's result and
    the PSO record for the model file."""
    import torch
    from tqdm import tqdm

    from .parallel import make_evaluator
    from .pso import PsoState, hyperparameter_space, optimize
    from .pso_plot import plot_convergence

    settings = replace(prof.pso, seed=args.seed)
    space = hyperparameter_space(settings)
    particle_dir = run_dir / "particles"
    particle_dir.mkdir(exist_ok=True)
    ctx = ParticleContext(
        train, val, normalizer, base, str(particle_dir.resolve()), particle_threads(args)
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
    saved = torch.load(particle_path(str(particle_dir), best), weights_only=True)
    net.load_state_dict(saved["state_dict"])
    net.eval()
    cfg = replace(
        base,
        learning_rate=10.0 ** float(best["log10_learning_rate"]),
        hidden_units=int(best["hidden_units"]),
    )
    summary = saved["summary"]
    tr = TrainResult(
        model=net,
        best_epoch=int(summary["best_epoch"]),
        best_val_mae_deg=float(saved["fitness"]),
        history=[EpochRecord(**r) for r in summary["history"]],
        seconds=float(summary["seconds"]),
        device=str(summary["device"]),
        stopped_early=bool(summary["stopped_early"]),
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
