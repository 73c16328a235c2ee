"""Offline accuracy of the estimator back-ends on generated bags → markdown table + JSON.

Each bag's samples go through the same :class:`~sideslip_estimator.estimator.Estimator`
the node runs (checks, alignment, window, back-end), one sample at a time in the order
twist, steering, IMU, so every IMU sample is aligned with the twist and steering of its
own stamp. Errors are β̂ − β in degrees against the bag's ground truth, over the samples
that got an estimate (the window must fill first: the first ``window_steps − 1`` samples
of a run have none, for every back-end alike).

Example (the paper-test scenarios at both noise levels)::

    sideslip-generate --preset paper-test --out /tmp/st-eval/paper --noise paper --force
    sideslip-generate --preset paper-test --out /tmp/st-eval/none --noise none --force
    python bench/offline_backends.py --data /tmp/st-eval --json /tmp/st-eval/backends.json

The model-based back-ends (``single_track``, ``ukf``) need the vehicle's parameters:
``--params-file`` names the shipped files of the vehicle the bags were generated with
(``--ukf-params-file`` sets the ukf's apart, e.g. a YAML path)::

    sideslip-generate --preset paper-test --vehicle compact_rwd --out /tmp/st-eval/compact \
        --noise paper --force
    python bench/offline_backends.py --data /tmp/st-eval/compact --params-file compact_rwd
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import subprocess
import sys
import time
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.replay import replay, replay_columns
from sideslip_msgs_py.bag import read_bag
from sideslip_msgs_py.sample import SampleArrays


@dataclass(frozen=True)
class BackendConfig:
    """A back-end and its parameter values, with the label the table shows."""

    label: str
    backend: str
    values: dict[str, object]


@dataclass(frozen=True)
class Metrics:
    """Errors β̂ − β [deg] over the samples with an estimate."""

    dataset: str
    scenario: str
    backend: str
    samples: int
    estimates: int
    rejected: int
    mae_deg: float
    me_deg: float
    rmse_deg: float
    max_abs_deg: float
    r2: float
    us_per_sample: float


def default_configs(
    smoothing: list[int], params_file: str, ukf_params_file: str | None = None
) -> list[BackendConfig]:
    configs = [
        BackendConfig(f"kinematic n={n}", "kinematic", {"smoothing_steps": n}) for n in smoothing
    ]
    configs.append(BackendConfig("single_track", "single_track", {"params_file": params_file}))
    ukf_file = ukf_params_file or params_file
    configs.append(BackendConfig("ukf", "ukf", {"params_file": ukf_file}))
    return configs


def estimate_run(
    samples: SampleArrays, config: BackendConfig, window_steps: int
) -> tuple[np.ndarray, int, float]:
    """β̂ per sample [rad] (NaN where none), rejected count, wall seconds."""
    est = Estimator(
        create_backend(config.backend, config.values, window_steps),
        EstimatorParams(window_steps=window_steps),
    )
    columns = replay_columns(samples)
    started = time.perf_counter()
    result = replay(est, columns)
    return result.beta_rad, result.rejected, time.perf_counter() - started


def metrics(
    dataset: str,
    scenario: str,
    backend: str,
    beta: np.ndarray,
    truth: np.ndarray,
    rejected: int,
    wall_s: float,
) -> Metrics:
    have = np.isfinite(beta)
    err = np.degrees(beta[have] - truth[have])
    truth_deg = np.degrees(truth[have])
    ss_tot = float(np.sum((truth_deg - truth_deg.mean()) ** 2)) if err.size else 0.0
    return Metrics(
        dataset=dataset,
        scenario=scenario,
        backend=backend,
        samples=int(beta.size),
        estimates=int(have.sum()),
        rejected=rejected,
        mae_deg=float(np.mean(np.abs(err))) if err.size else math.nan,
        me_deg=float(np.mean(err)) if err.size else math.nan,
        rmse_deg=float(np.sqrt(np.mean(err**2))) if err.size else math.nan,
        max_abs_deg=float(np.max(np.abs(err))) if err.size else math.nan,
        r2=1.0 - float(np.sum(err**2)) / ss_tot if ss_tot > 0 else math.nan,
        us_per_sample=wall_s / max(beta.size, 1) * 1e6,
    )


def find_datasets(data: Path) -> dict[str, list[Path]]:
    """Dataset name → bag directories: ``data`` itself or each sub-folder holding bags."""

    def bags_in(folder: Path) -> list[Path]:
        return sorted(p for p in folder.iterdir() if (p / "metadata.yaml").is_file())

    if bags := bags_in(data):
        return {_dataset_name(data): bags}
    found = {}
    for sub in sorted(p for p in data.iterdir() if p.is_dir()):
        if bags := bags_in(sub):
            found[_dataset_name(sub)] = bags
    return found


def _dataset_name(folder: Path) -> str:
    index = folder / "index.json"
    if index.is_file():
        info = json.loads(index.read_text())
        return f"{folder.name} (noise {info.get('noise', '?')}, seed {info.get('seed', '?')})"
    return folder.name


def evaluate(
    datasets: dict[str, list[Path]], configs: list[BackendConfig], window_steps: int
) -> list[Metrics]:
    results: list[Metrics] = []
    for dataset, bags in datasets.items():
        pooled: dict[str, list[tuple[np.ndarray, np.ndarray, int, float]]] = {}
        for bag in bags:
            samples = read_bag(bag).samples
            truth = samples.beta_rad()
            for cfg in configs:
                beta, rejected, wall = estimate_run(samples, cfg, window_steps)
                results.append(metrics(dataset, bag.name, cfg.label, beta, truth, rejected, wall))
                pooled.setdefault(cfg.label, []).append((beta, truth, rejected, wall))
                print(f"  {dataset} {bag.name} {cfg.label}: done", file=sys.stderr)
        for label, runs in pooled.items():
            beta = np.concatenate([r[0] for r in runs])
            truth = np.concatenate([r[1] for r in runs])
            rej = sum(r[2] for r in runs)
            wall = sum(r[3] for r in runs)
            results.append(metrics(dataset, "all", label, beta, truth, rej, wall))
    return results


def markdown_table(results: list[Metrics]) -> str:
    columns = ("data", "scenario", "back-end", "MAE °", "RMSE °", "ME °", "max °", "R²",
               "estimates", "µs/sample")  # fmt: skip
    lines = ["| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    for m in results:
        lines.append(
            f"| {m.dataset} | {m.scenario} | {m.backend} | {m.mae_deg:.3f} | {m.rmse_deg:.3f} "
            f"| {m.me_deg:+.3f} | {m.max_abs_deg:.3f} | {m.r2:.4f} | {m.estimates}/{m.samples} "
            f"| {m.us_per_sample:.1f} |"
        )
    return "\n".join(lines)


def _git_commit() -> str:
    try:
        out = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=False
        )
    except OSError:
        return "unknown"
    return out.stdout.strip() or "unknown"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python bench/offline_backends.py",
        description="Run generated bags through the estimator core with each back-end and "
        "report MAE, RMSE, ME, max |error| [deg] and R² against the ground truth, per bag "
        "and pooled per data set.",
    )
    parser.add_argument(
        "--data",
        required=True,
        type=Path,
        help="a folder of bags (sideslip-generate --out), or a folder of such folders",
    )
    parser.add_argument("--json", type=Path, help="write the results as JSON to this path")
    parser.add_argument(
        "--smoothing",
        type=int,
        nargs="+",
        default=[1, 20, 100],
        help="kinematic smoothing_steps values to compare (default: 1 20 100)",
    )
    parser.add_argument(
        "--params-file",
        default="paper_sedan",
        help="single_track params_file: a shipped name (the vehicle's, e.g. compact_rwd) "
        "or a YAML path (default paper_sedan)",
    )
    parser.add_argument(
        "--ukf-params-file",
        help="ukf params_file: a shipped name or a YAML path (default: --params-file, "
        "which names both back-ends' shipped files of a vehicle)",
    )
    parser.add_argument("--window-steps", type=int, default=100, help="window length (100)")
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not args.data.is_dir():
        print(f"offline_backends: error: --data {args.data} is not a folder", file=sys.stderr)
        return 2
    datasets = find_datasets(args.data)
    if not datasets:
        print(f"offline_backends: error: no bags under {args.data}", file=sys.stderr)
        return 2
    try:
        configs = default_configs(args.smoothing, args.params_file, args.ukf_params_file)
        for cfg in configs:  # refuse bad settings before any work
            create_backend(cfg.backend, cfg.values, args.window_steps)
    except ValueError as err:
        print(f"offline_backends: error: {err}", file=sys.stderr)
        return 2
    results = evaluate(datasets, configs, args.window_steps)
    print(markdown_table(results))
    if args.json:
        report = {
            "command": " ".join([Path(sys.argv[0]).name, *(argv or sys.argv[1:])]),
            "when": datetime.now(UTC).isoformat(timespec="seconds"),
            "commit": _git_commit(),
            "python": platform.python_version(),
            "window_steps": args.window_steps,
            "datasets": {name: [str(b) for b in bags] for name, bags in datasets.items()},
            "backends": [asdict(c) for c in configs],
            "results": [asdict(m) for m in results],
        }
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    sys.exit(main())
