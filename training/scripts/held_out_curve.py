"""Learning curve on a held-out car (issue 9): fine-tuned vs from scratch vs zero-shot,
with 1, 2, 5, 10 and 20 minutes of the car's own data.

The car's data: fleet-style runs (6-12 s each, μ 0.3-1.0, paper noise) of the held-out
car itself, other seeds and manoeuvres than its benchmark runs, built with
``fleet_runs`` directly (the training presets refuse held-out cars; this yardstick is
never shipped). For each amount, the first runs whose durations add up to it:

* **fine-tuned**: ``sideslip-train --init fleet_lstm_paper --profile quick`` (the
  shipped model's inputs, prior and normalisation kept);
* **scratch**: the same network from random weights: ``--model lstm --hidden-units 32
  --features paper_kinematic --prior kinematic_window --profile quick``;
* **zero-shot**: ``fleet_lstm_paper`` as shipped.

``--base measurable`` does the same with ``fleet_ukf_measurable`` (no Y_v; a residual
on the UKF, which runs with the car's parameters from its bags) and its recipe (64
units, ``measurable_observer_signals``, ``--prior ukf``). ``--train-args`` are added to
both trainings (e.g. ``--stride 10 --mirror no`` for a quicker comparison than the
small-data defaults).

``--start`` fine-tunes another model than the base's shipped one (a shipped name or a
file with the base's inputs and prior, e.g. ``fleet_ukf_merged``); it is the zero-shot
model then too. ``--no-scratch`` leaves the scratch training out (it does not depend on
the start: the same data, seeds and recipe give the same network), so ``curve.json``
has no scratch figure.

``--finetune-args`` are added to the fine-tuning only (``--interpolate 0.5``, as
``sideslip-fit --bags`` fine-tunes).

``--eval-args`` are added to the scoring (the car files a user's node would run, when
``--train-args`` gave the trainings such files; ``--tag`` keeps that run's folder apart).

Both trainings take their validation split from the same runs (``--split auto``); all
three are scored once on the car's 18 held-out benchmark runs. Results (pooled MAE
[deg]) in ``OUT/CAR/curve.json`` and ``OUT/CAR/curve.md``.

    python training/scripts/held_out_curve.py --car heldout_sports_rwd --out data/held-out-curve
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

from sideslip_sim.generate import generate, prepare_output
from sideslip_sim.held_out import held_out_vehicles
from sideslip_sim.presets import FLEET_RUNS_PER_CAR, VehicleRun, fleet_runs
from sideslip_sim.vehicle import VehicleParams
from sideslip_training.cli import train_main
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.fit import SHIPPED_PAPER
from sideslip_training.init_model import resolve

MINUTES = (1.0, 2.0, 5.0, 10.0, 20.0)
BASES = {
    "paper": (
        SHIPPED_PAPER,
        ["--model", "lstm", "--hidden-units", "32", "--features", "paper_kinematic",
         "--prior", "kinematic_window"],
    ),
    "measurable": (
        "fleet_ukf_measurable",
        ["--model", "lstm", "--hidden-units", "64", "--features", "measurable_observer_signals",
         "--prior", "ukf"],
    ),
}  # fmt: skip


def car_runs(name: str, minutes: float, seed: int) -> list[VehicleRun]:
    """Fleet-style runs of the held-out car ``name``, at least ``minutes`` of driving."""
    return own_runs(held_out_vehicles()[name], minutes, seed)


def own_runs(car: VehicleParams, minutes: float, seed: int) -> list[VehicleRun]:
    """Fleet-style runs of ``car`` itself (named ``ownNNN_family``), at least ``minutes``
    of driving."""
    cars = int(minutes * 60 / (6.0 * FLEET_RUNS_PER_CAR)) + 1  # runs last 6-12 s
    runs = fleet_runs([car] * cars, FLEET_RUNS_PER_CAR * cars, seed)
    return [
        VehicleRun(
            r.vehicle, dataclasses.replace(r.maneuver, name=f"own{i:03d}_{r.maneuver.family}")
        )
        for i, r in enumerate(runs)
    ]


def write_own_minutes(
    car: VehicleParams, minutes: float, seed: int, folder: Path, preset: str, jobs: int = 1
) -> bool:
    """Generate into ``folder`` the first ``minutes`` of ``car``'s own runs
    (:func:`own_runs`, with ``generate``'s defaults otherwise), unless ``folder``
    already holds a finished set (its ``index.json``). True when it generated them."""
    if (folder / "index.json").exists():
        return False
    runs = own_runs(car, minutes, seed)
    runs = runs[: len(first_minutes(runs, minutes))]
    prepare_output(folder, force=True)
    generate(runs, folder, seed=seed, preset_name=preset, jobs=jobs, progress=False)
    return True


def made_from(model: Path) -> str:
    """The file name of the model ``model`` was fine-tuned from ("" if from scratch)."""
    from sideslip_msgs_py.artifact import read_artifact

    return str(read_artifact(model)[1].provenance.get("init") or "")


def first_minutes(runs: list[VehicleRun], minutes: float) -> list[str]:
    """Names of the first runs whose durations add up to ``minutes``."""
    out, total = [], 0.0
    for r in runs:
        if total >= minutes * 60.0:
            break
        out.append(r.maneuver.name)
        total += r.maneuver.duration_s
    return out


def pooled_mae(report: Path) -> dict[str, float]:
    """Pooled MAE [deg] per estimator of a sideslip-evaluate report."""
    summary = json.loads((report / "metrics.json").read_text())
    return {r["estimator"]: r["mae"] for r in summary["pooled"] if r["mae"] is not None}


def model_mae(report: Path, model: Path) -> float:
    """Pooled MAE [deg] of the model file ``model`` in a sideslip-evaluate report."""
    label = json.loads((report / "metrics.json").read_text())["model_estimators"][str(model)]
    return pooled_mae(report)[label]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--car", default="heldout_sports_rwd")
    p.add_argument("--held-out", type=Path, default=Path("data/held-out"))
    p.add_argument("--out", type=Path, default=Path("data/held-out-curve"))
    p.add_argument("--minutes", type=float, nargs="+", default=list(MINUTES))
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--base", choices=sorted(BASES), default="paper", help="which shipped model")
    p.add_argument("--train-args", default="", help="more sideslip-train options for both")
    p.add_argument(
        "--finetune-args",
        default="",
        help="more sideslip-train options for the fine-tuning only (e.g. --interpolate 0.5)",
    )
    p.add_argument(
        "--eval-args",
        default="",
        help="more sideslip-evaluate options (e.g. the car files the trainings were given: "
        "--vehicle D --observer-params F --car given --ukf-params F)",
    )
    p.add_argument("--start", default=None, help="the model to fine-tune (default: the base's)")
    p.add_argument("--no-scratch", action="store_true", help="no training from scratch")
    p.add_argument("--tag", default="", help="suffix of the work folder (CAR-BASE-TAG)")
    args = p.parse_args(argv)
    shipped, scratch_model = BASES[args.base]
    start = resolve(args.start or shipped, "--start")
    work = args.out / args.car if args.base == "paper" else args.out / f"{args.car}-{args.base}"
    if args.tag:
        work = work.with_name(f"{work.name}-{args.tag}")
    data = work / "data"
    runs = car_runs(args.car, max(args.minutes), args.seed)
    runs = runs[: len(first_minutes(runs, max(args.minutes)))]
    # A later call with more minutes needs more runs than an earlier one generated; the
    # seeded sequence is the same, so the earlier runs come back unchanged.
    if not all((data / r.maneuver.name).exists() for r in runs):
        prepare_output(data, force=True)
        generate(runs, data, seed=args.seed, preset_name="held-out-own (yardstick only)",
                 jobs=2, progress=False)  # fmt: skip
    bags = sorted(str(b) for b in args.held_out.glob(f"{args.car}_mu*"))
    if len(bags) != 18:
        print(f"{args.car}: expected 18 held-out runs under {args.held_out}, got {len(bags)}")
        return 2
    common = ["--profile", "quick", "--device", "cpu", "--seed", str(args.seed), "--quiet"]
    common += args.train_args.split()
    curve = {}
    for minutes in args.minutes:
        names = first_minutes(runs, minutes)
        subset = [str(data / n) for n in names]
        models = {}
        fine_tune = ["--init", str(start), *args.finetune_args.split()]
        kinds = [("finetuned", fine_tune)] + [("scratch", scratch_model)] * (not args.no_scratch)
        for kind, extra in kinds:
            out = work / f"{kind}_{minutes:g}min.safetensors"
            origin = made_from(out) if out.exists() and kind == "finetuned" else None
            if origin is not None and origin != start.name:
                print(f"{out} was fine-tuned from {origin}, not {start.name}: use --tag")
                return 2
            if not out.exists():
                code = train_main(
                    ["--data", *subset, "--out", str(out), "--force", *extra, *common]
                )
                if code:
                    return code
            models[kind] = out
        report = work / f"report_{minutes:g}min"
        code = evaluate_main(["--model", *(str(m) for m in models.values()), str(start),
                              "--data", *bags, "--out", str(report), "--force",
                              *args.eval_args.split()])  # fmt: skip
        if code:
            return code
        curve[f"{minutes:g}"] = {
            "runs": len(names),
            "start": start.stem,
            "finetuned": model_mae(report, models["finetuned"]),
            "scratch": model_mae(report, models["scratch"]) if "scratch" in models else None,
            "zero_shot": model_mae(report, start),
        }
        print(f"{args.car} {minutes:g} min: {curve[f'{minutes:g}']}", file=sys.stderr)
    done = work / "curve.json"
    # Calls for other amounts of the same work folder add to the curve, not replace it.
    curve = {**(json.loads(done.read_text()) if done.exists() else {}), **curve}
    curve = dict(sorted(curve.items(), key=lambda item: float(item[0])))
    done.write_text(json.dumps(curve, indent=2) + "\n")
    lines = ["| minutes | runs | fine-tuned | scratch | zero-shot | fine-tuned vs scratch |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    for m, c in curve.items():
        scratch = "—" if c["scratch"] is None else f"{c['scratch']:.4f}"
        gain = "—" if c["scratch"] is None else f"{1.0 - c['finetuned'] / c['scratch']:+.0%}"
        lines.append(
            f"| {m} | {c['runs']} | {c['finetuned']:.4f} | {scratch} | "
            f"{c['zero_shot']:.4f} | {gain} |"
        )
    (work / "curve.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
