"""Noise tuning of the estimator's ``ukf`` back-end on training bags, with the project's PSO.

The UKF's sigmas (measurement noise that also stands for model error, and process noise)
are not sensor data sheets: they are tuned. The fitness of a candidate is the RMSE [deg]
of β̂ − β, pooled over every sample that got an estimate, when the training bags are
replayed through the estimator core (:class:`~sideslip_estimator.estimator.Estimator`,
the same alignment, window and back-end the node runs; twist, steering, then IMU per
sample, as ``bench/offline_backends.py`` does). PSO (:mod:`.pso`) searches log10 of each
tuned sigma within ``±decades`` of the back-end's default; the defaults count as one
more candidate, so the result is never worse than them on the training bags.

Only training bags may be given: the result becomes the back-end's defaults, which are
then scored on test data and held-out vehicles that no tuning saw.

``--params-file recorded`` tunes over many cars at once: each bag is replayed with the
``ukf`` params of the car its metadata records (its true nominal values, effective axles,
as ``sideslip-train``'s observer and the held-out benchmark give the filter) and that
car's steering limit (:func:`~.physics_params.steering_limit_m`), e.g. fleet training
bags (``sideslip-generate --preset fleet --seed 1``).

This module imports ``sideslip_estimator``: the back-end under tuning.

How the shipped defaults were tuned (2 workers; 54 training bags, 0.2 M samples)::

    sideslip-generate --preset paper-train --out /tmp/ukf-train/paper --noise paper
    sideslip-generate --preset randomized --count 24 --seed 101 \\
        --out /tmp/ukf-train/rand101 --noise paper
    # /tmp/ukf-train/subset: links to every 4th paper-train bag (sorted) and all of rand101
    python -m sideslip_training.ukf_tuning --data /tmp/ukf-train/subset \\
        --params-file paper_sedan --swarm 6 --iterations 3 --workers 2 --out ukf_tuning.json

(the second of two rounds; the first, 8 × 5 evaluations, gave the defaults this one is
centred on). Each evaluation replays every bag once: about 1 min per particle here.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from sideslip_estimator.backends import BackendError, create_backend
from sideslip_estimator.backends.ukf import TUNED_PARAMETERS, UkfBackend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.replay import replay as replay_samples
from sideslip_estimator.replay import replay_columns
from sideslip_msgs_py.bag import read_bag

from .config import WINDOW_STEPS, PsoSettings
from .parallel import EvaluationError, make_evaluator
from .pso import Dimension, FailedFitness, PsoError, PsoState, SearchSpace, optimize

DEFAULT_DECADES = 1.0
_DEFAULTS = {p.name: p.default for p in UkfBackend.parameters}


class TuningError(ValueError):
    """No usable bag, a bad parameter name, or settings the back-end refuses."""


RECORDED = "recorded"
"""``params_file`` value: each bag's own recorded car (module doc)."""


@dataclass(frozen=True)
class ReplayRun:
    """One bag's samples as plain columns (cheap to send to worker processes)."""

    name: str
    columns: tuple[Sequence[float | int], ...]
    """stamp, X_v, Y_v, X_a, Y_a, ψ̇, STL, STL rate per sample (Python numbers)."""
    beta_rad: np.ndarray
    car_params: str | None = None
    """The ``ukf`` params file text of the bag's recorded car (with ``recorded``)."""
    stl_limit_m: float | None = None
    """That car's steering limit [m] for the estimator's input check (``recorded``)."""


def load_replay_runs(bags: Sequence[str | Path], *, recorded: bool = False) -> list[ReplayRun]:
    """Each bag (a rosbag2 folder, or a folder of them) with ground truth, read once;
    ``recorded``: with the params of the car its metadata records (refused without one)."""
    paths: list[Path] = []
    for b in map(Path, bags):
        if (b / "metadata.yaml").is_file() or b.suffix == ".mcap":
            paths.append(b)
        elif b.is_dir():
            paths.extend(sorted(p for p in b.iterdir() if (p / "metadata.yaml").is_file()))
        else:
            raise TuningError(f"{b}: not a bag or a folder of bags")
    if not paths:
        raise TuningError(f"no bags under {', '.join(map(str, bags))}")
    runs = []
    for path in paths:
        bag = read_bag(path)
        beta = bag.samples.beta_rad()
        if not np.any(np.isfinite(beta)):
            raise TuningError(f"{path}: no ground truth (tuning needs β)")
        car: tuple[str | None, float | None] = (None, None)
        if recorded:
            car = _recorded_car(path, bag.run_metadata.get("vehicle"))
        runs.append(ReplayRun(path.name, replay_columns(bag.samples), beta, *car))
    return runs


def _recorded_car(path: Path, vehicle: object) -> tuple[str, float]:
    """(``ukf`` params file text, steering limit [m]) of the car a bag records."""
    from .dataset import DatasetError
    from .observer import BACKEND, params_of_vehicle
    from .physics_params import params_yaml, steering_limit_m

    if not isinstance(vehicle, Mapping):
        raise TuningError(f"{path}: --params-file {RECORDED}, but the bag records no vehicle")
    try:
        params = params_of_vehicle(vehicle)
        limit = steering_limit_m(vehicle)
    except (DatasetError, KeyError, ValueError) as err:
        raise TuningError(f"{path}: its recorded vehicle gives no ukf params: {err}") from None
    text = params_yaml(BACKEND, str(params.get("name", path.name)), params, "ukf_tuning")
    return text, limit


def replay(run: ReplayRun, values: Mapping[str, object]) -> np.ndarray:
    """β̂ [rad] per sample of ``run`` from the ukf back-end with ``values`` (NaN: none);
    a run with its own car is replayed with that car's params and steering limit."""
    if run.car_params is None:
        backend = create_backend(UkfBackend.name, values, WINDOW_STEPS)
        params = EstimatorParams(window_steps=WINDOW_STEPS)
    else:
        from sideslip_estimator.inputs import InputLimits

        # The back-end reads its car from a file: one per call, gone once it is built.
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "car.ukf.yaml"
            path.write_text(run.car_params, encoding="utf-8")
            backend = create_backend(
                UkfBackend.name, {**values, "params_file": str(path)}, WINDOW_STEPS
            )
        limits = InputLimits(stl_m=run.stl_limit_m) if run.stl_limit_m else InputLimits()
        params = EstimatorParams(window_steps=WINDOW_STEPS, limits=limits)
    return replay_samples(Estimator(backend, params), run.columns).beta_rad


def beta_rmse_deg(runs: Sequence[ReplayRun], values: Mapping[str, object]) -> float:
    """RMSE [deg] of β̂ − β pooled over the samples of ``runs`` that got an estimate."""
    sq, n = 0.0, 0
    for run in runs:
        err = np.degrees(replay(run, values) - run.beta_rad)
        err = err[np.isfinite(err)]
        sq += float(np.sum(err * err))
        n += err.size
    return math.sqrt(sq / n) if n else math.inf


@dataclass(frozen=True)
class _Context:
    runs: tuple[ReplayRun, ...]
    fixed: dict[str, object]


def _fitness(params: dict[str, Any], context: _Context) -> float:
    """One particle: its sigmas (10^position) over the fixed values, replayed."""
    values = dict(context.fixed)
    values.update({k.removeprefix("log10_"): 10.0 ** float(v) for k, v in params.items()})
    try:
        return beta_rmse_deg(context.runs, values)
    except BackendError as err:
        return FailedFitness(str(err))


def search_space(
    names: Sequence[str] = TUNED_PARAMETERS,
    decades: float = DEFAULT_DECADES,
    center: Mapping[str, float] | None = None,
) -> SearchSpace:
    """log10 of each tuned sigma in [log10 c − decades, log10 c + decades], c = ``center``
    (default: the back-end's defaults)."""
    unknown = sorted(set(names) - set(TUNED_PARAMETERS))
    if unknown:
        raise TuningError(f"not tunable: {unknown} (tunable: {', '.join(TUNED_PARAMETERS)})")
    if not (math.isfinite(decades) and decades > 0.0):
        raise TuningError(f"decades must be > 0, got {decades!r}")
    center = {**_DEFAULTS, **(center or {})}
    out = []
    for name in names:
        c = math.log10(float(center[name]))  # type: ignore[arg-type]
        out.append(Dimension(f"log10_{name}", c - decades, c + decades))
    return tuple(out)


@dataclass(frozen=True)
class TuningResult:
    """Chosen sigmas, their training RMSE, the defaults' RMSE, and the PSO history."""

    params_file: str
    bags: tuple[str, ...]
    samples: int
    best_values: dict[str, float]
    best_rmse_deg: float
    default_rmse_deg: float
    pso_evaluations: int
    wall_s: float
    pso_history: dict[str, Any] = field(repr=False)

    def to_json(self) -> str:
        return json.dumps(self.__dict__, indent=1, allow_nan=False) + "\n"


def tune(
    runs: Sequence[ReplayRun],
    params_file: str,
    settings: PsoSettings,
    *,
    names: Sequence[str] = TUNED_PARAMETERS,
    decades: float = DEFAULT_DECADES,
    fixed: Mapping[str, object] | None = None,
    workers: int = 1,
    on_iteration: Callable[[PsoState], None] | None = None,
) -> TuningResult:
    """PSO over log10 of the ``names`` sigmas minimising the training β RMSE (module doc).

    ``fixed``: other back-end values held during the search (e.g. ``estimate_friction``).
    The back-end's defaults (with ``fixed``) are evaluated too and win ties.
    ``on_iteration`` is :func:`~.pso.optimize`'s (called after each swarm evaluation).
    """
    if not runs:
        raise TuningError("no training runs")
    if params_file == RECORDED and any(r.car_params is None for r in runs):
        raise TuningError(f"--params-file {RECORDED}: runs without their car's params")
    # With each run's own car, the shipped default car only checks the settings here.
    checked = "paper_sedan" if params_file == RECORDED else params_file
    fixed_values = {"params_file": checked, **(fixed or {})}
    try:  # refuse bad settings before any replay
        create_backend(UkfBackend.name, fixed_values, WINDOW_STEPS)
    except BackendError as err:
        raise TuningError(str(err)) from None
    space = search_space(names, decades)
    context = _Context(tuple(runs), dict(fixed_values))
    started = time.perf_counter()
    with make_evaluator(_fitness, context, workers=workers, ray_address=None) as evaluate:
        result = optimize(evaluate, space, settings, on_iteration=on_iteration)
    default_rmse = beta_rmse_deg(runs, fixed_values)
    best = {d.name.removeprefix("log10_"): 10.0 ** result.best_params[d.name] for d in space}
    best_rmse = float(result.best_fitness)
    if not best_rmse < default_rmse:
        best_rmse = default_rmse
        best = {n: float(_DEFAULTS[n]) for n in best}  # type: ignore[arg-type]
    return TuningResult(
        params_file=params_file,
        bags=tuple(r.name for r in runs),
        samples=sum(len(r.beta_rad) for r in runs),
        best_values={k: float(f"{v:.4g}") for k, v in best.items()},
        best_rmse_deg=best_rmse,
        default_rmse_deg=default_rmse,
        pso_evaluations=result.evaluations,
        wall_s=time.perf_counter() - started,
        pso_history=result.history.to_dict(),
    )


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m sideslip_training.ukf_tuning",
        description="Tune the ukf back-end's noise sigmas (log10, PSO) to minimise the RMSE "
        "of β on TRAINING bags replayed through the estimator core. Prints the chosen "
        "values; --out writes them with the PSO history as JSON.",
    )
    p.add_argument(
        "--data",
        nargs="+",
        required=True,
        type=Path,
        help="training bags or folders of bags (never test data)",
    )
    p.add_argument(
        "--params-file",
        default="paper_sedan",
        help="ukf params_file: shipped name or YAML path (default paper_sedan), or "
        f"'{RECORDED}': each bag's own recorded car (e.g. fleet training bags)",
    )
    p.add_argument("--swarm", type=int, default=8, help="PSO particles (default 8)")
    p.add_argument("--iterations", type=int, default=4, help="PSO iterations (default 4)")
    p.add_argument("--seed", type=int, default=0, help="PSO seed (default 0)")
    p.add_argument(
        "--decades",
        type=float,
        default=DEFAULT_DECADES,
        help="search ± this many decades around each default (default 1)",
    )
    p.add_argument(
        "--names",
        nargs="+",
        default=list(TUNED_PARAMETERS),
        help=f"sigmas to tune (default all: {' '.join(TUNED_PARAMETERS)})",
    )
    p.add_argument("--workers", type=int, default=1, help="worker processes (default 1)")
    p.add_argument("--out", type=Path, help="write the result as JSON here")
    p.add_argument("--force", action="store_true", help="replace an existing --out")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.out is not None and args.out.exists() and not args.force:
        print(f"ukf_tuning: error: {args.out} exists (use --force)", file=sys.stderr)
        return 2
    try:
        runs = load_replay_runs(args.data, recorded=args.params_file == RECORDED)
        settings = PsoSettings(iterations=args.iterations, swarm_size=args.swarm, seed=args.seed)
        bar = tqdm(total=args.iterations + 1, unit="swarm", desc="ukf tuning", file=sys.stderr)

        def progress(state: PsoState) -> None:
            bar.set_postfix_str(f"best RMSE {state.global_best_fitness:.4f}°")
            bar.update()

        result = tune(
            runs,
            args.params_file,
            settings,
            names=args.names,
            decades=args.decades,
            workers=args.workers,
            on_iteration=progress,
        )
        bar.close()
    except (TuningError, PsoError, EvaluationError, ValueError, OSError) as err:
        print(f"ukf_tuning: error: {err}", file=sys.stderr)
        return 2
    print(
        f"{len(runs)} bags, {result.samples} samples, {result.pso_evaluations} evaluations, "
        f"{result.wall_s:.0f} s"
    )
    print(
        f"β RMSE on the training bags: defaults {result.default_rmse_deg:.4f}°, "
        f"tuned {result.best_rmse_deg:.4f}°"
    )
    for name, value in result.best_values.items():
        print(f"  ukf.{name}: {value}")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        args.out.write_text(result.to_json(), encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
