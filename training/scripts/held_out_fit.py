"""sideslip-fit from each held-out car's short description against a model trained on
that car's exact simulation (issue 9's "≤ 1.5×"), scored on the held-out benchmark.

For every held-out car (``sideslip_sim.held_out``):

* **fit**: ``sideslip-fit --vehicle DESC --profile quick`` (``paper`` features: fine-tunes
  ``fleet_lstm_paper``), where DESC holds only what an owner can look up (the seven
  numbers of :class:`~sideslip_msgs_py.vehicle_description.VehicleDescription` and the
  drive layout), not the car's parameter file;
* **exact**: the same recipe (``sideslip-train --init fleet_lstm_paper --profile quick``)
  on the same amount of driving (12 × 4 fleet-style runs, μ 0.3-1.0, paper noise) of the
  car itself, its exact parameters: the reference a fit is measured against. It exists
  only here, as a yardstick, and is never shipped; the training presets keep refusing
  held-out cars (its runs are built with ``fleet_runs`` directly, other seeds and
  manoeuvres than the benchmark's);
* **zero-shot**: the shipped ``fleet_lstm_paper``.

All three are scored once on the car's 18 held-out benchmark runs (``data/held-out``,
``sideslip-benchmark --generate``); nothing is selected on them. Pooled MAE per car and
the ratio fit / exact go to ``OUT/summary.json`` and ``OUT/table.md``.

    python training/scripts/held_out_fit.py --held-out data/held-out --out data/held-out-fit

Models are scored as the node runs them (``--mirror-average auto``); ``--mirror-average
yes`` re-scores fits written before models recorded their training data's source.

``--features measurable`` (no Y_v) asks what a user with only the description gets: the
fit fine-tunes its default start (``fleet_ukf_described`` since 2026-12-04, before that
``fleet_ukf_measurable``; ``fit_validation.py`` compares starts) with the UKF run on the
described car (:mod:`sideslip_sim.described_car`). Scored with the described car's
files, as the node would run them (``--car given``): the fit, the zero-shot
``fleet_ukf_measurable`` and the UKF; beside them the zero-shot model and the UKF with
the car's true parameters, which a user without its tyre data does not have. ``--exact``
adds the yardstick of issue 9: the fit's own recipe (``sideslip-train --init
fleet_ukf_measurable``, the quick profile's epochs, no mirroring) on the car's exact
simulation, the UKF run on each bag's true car, scored with the car's true files; ``fit
/ exact`` then compares what a description gives with what the car's own simulation
gives.
``--zero-shot`` leaves the fit out (minutes instead of an hour): the shipped model and
the UKF with the described and with the true car's files. ``--identify MINUTES`` adds
both with the axles identified from that much of the car's own labelled driving
(``sideslip-identify-axles`` from the description; the learning curve's runs of the car,
``held_out_curve.py``'s seed 7, paper noise), no training.

    python training/scripts/held_out_fit.py --features measurable --out data/held-out-fit-measurable
    python training/scripts/held_out_fit.py --features measurable --zero-shot --identify 5 \
        --out data/held-out-fit-measurable-zs
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import yaml

from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_sim.generate import generate, prepare_output
from sideslip_sim.held_out import held_out_vehicles
from sideslip_sim.presets import FLEET_RUNS_PER_CAR, VehicleRun, fleet_runs
from sideslip_sim.vehicle import VehicleParams, vehicle_record
from sideslip_training.cli import train_main
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.fit import (
    FIT_PROFILES,
    SHIPPED_MEASURABLE,
    SHIPPED_PAPER,
    Description,
    recipe_options,
)
from sideslip_training.fit import main as fit_main
from sideslip_training.identify_axles import main as identify_main
from sideslip_training.init_model import resolve
from sideslip_training.inputs import add_mirror_average_argument
from sideslip_training.physics_params import nominal_parameters, params_yaml

PROFILE = FIT_PROFILES["quick"]
OWN_SEED = 7
"""Seed of a car's own runs for ``--identify``: the learning curve's (held_out_curve.py)."""


def description(car: VehicleParams) -> dict[str, object]:
    """What an owner can look up about ``car``: the description keys and the layout."""
    nominal = VehicleDescription.from_mapping(dataclasses.asdict(car), where=car.name)
    return {"name": car.name, **nominal.to_dict(), "drive_layout": car.drive_layout}


def observer_file_args(desc: Path, ukf: Path) -> list[str]:
    """``sideslip-evaluate`` options that run the UKF and the observer-reading models on
    ``ukf`` for a car known only by its description ``desc``."""
    return ["--vehicle", str(desc), "--observer-params", str(ukf), "--car", "given",
            "--ukf-params", str(ukf)]  # fmt: skip


def write_true_ukf(car: VehicleParams, path: Path, tool: str) -> Path:
    """The car's true ``ukf`` file (its nominal parameters), written by ``tool``."""
    path.write_text(
        params_yaml("ukf", car.name, nominal_parameters("ukf", vehicle_record(car)), tool)
    )
    return path


def exact_runs(car: VehicleParams, seed: int) -> list[VehicleRun]:
    """The fit's amount of driving, all of it on ``car`` itself, turning both ways as the
    fit's fleet does (since 2026-12-05)."""
    count = FLEET_RUNS_PER_CAR * PROFILE.cars
    runs = fleet_runs([car] * PROFILE.cars, count, seed, both_sides=True)
    return [
        VehicleRun(
            r.vehicle, dataclasses.replace(r.maneuver, name=f"exact{i:03d}_{r.maneuver.family}")
        )
        for i, r in enumerate(runs)
    ]


def pooled_mae(report: Path, stems: list[str], lone: str | None = None) -> dict[str, float]:
    """Pooled MAE [deg] per model file stem (sideslip-evaluate names models of the same
    kind "LABEL (stem)") and per baseline, from a report folder. A report of one model
    labels it "ARCH [features]..." without a stem: ``lone`` names it then."""
    summary = json.loads((report / "metrics.json").read_text())
    # Reports that map model files to their rows name the models whatever the labels
    # (two models of different kinds carry no stem in theirs).
    by_label = {
        label: Path(path).stem
        for path, label in summary.get("model_estimators", {}).items()
        if Path(path).stem in stems
    }
    out = {}
    for r in summary["pooled"]:
        if r["mae"] is None:
            continue
        name = r["estimator"]
        tag = by_label.get(name) or next((s for s in stems if name.endswith(f"({s})")), name)
        if tag == name and lone is not None and "[" in name:
            tag = lone
        out[tag] = r["mae"]
    return out


class _Failed(Exception):
    def __init__(self, code: int) -> None:
        self.code = code


def fit_car(
    args: argparse.Namespace, name: str, car: VehicleParams, work: Path
) -> tuple[list[str], Path, Path, float]:
    """The car's 18 benchmark bags, its description file, and ``sideslip-fit`` from it
    (``args.features``; skipped when ``work/fit.safetensors`` exists, and with
    ``--zero-shot``, which writes only the described car's ``fit.ukf.yaml``) with its
    wall time."""
    work.mkdir(parents=True, exist_ok=True)
    bags = sorted(str(b) for b in args.held_out.glob(f"{name}_mu*"))
    if len(bags) != 18:
        print(f"{name}: expected 18 held-out runs under {args.held_out}, got {len(bags)}")
        raise _Failed(2)
    started = time.perf_counter()
    desc = work / "description.yaml"
    desc.write_text(yaml.safe_dump(description(car), sort_keys=False))
    fit = work / "fit.safetensors"
    if getattr(args, "zero_shot", False):
        fit.with_suffix(".ukf.yaml").write_text(Description.load(desc).ukf_params_yaml())
    elif not fit.exists():
        code = fit_main(["--vehicle", str(desc), "--out", str(fit), "--profile", "quick",
                         "--features", args.features, "--seed", str(args.seed),
                         "--quiet"])  # fmt: skip
        if code:
            raise _Failed(code)
    return bags, desc, fit, time.perf_counter() - started


def train_exact(
    args: argparse.Namespace, car: VehicleParams, work: Path, recipe: list[str]
) -> Path:
    """The yardstick: ``sideslip-train`` with ``recipe`` on the fit's amount of driving of
    ``car`` itself (skipped when ``work/exact.safetensors`` exists)."""
    exact = work / "exact.safetensors"
    if exact.exists():
        return exact
    data = work / "exact-train"
    prepare_output(data, force=True)
    generate(exact_runs(car, args.seed), data, seed=args.seed,
             preset_name="held-out-exact (yardstick only)", jobs=2, progress=False)  # fmt: skip
    code = train_main(["--data", str(data), "--out", str(exact), "--force", "--seed",
                       str(args.seed), "--device", "cpu", "--quiet", *recipe])  # fmt: skip
    if code:
        raise _Failed(code)
    return exact


# The exact-simulation yardstick trains as the measurable fit does, on each bag's true car.
MEASURABLE_RECIPE = ["--init", SHIPPED_MEASURABLE, *recipe_options(PROFILE)]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--held-out", type=Path, default=Path("data/held-out"))
    p.add_argument("--out", type=Path, default=Path("data/held-out-fit"))
    p.add_argument("--cars", nargs="*", help="held-out car names (default: all six)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--features", choices=["paper", "measurable"], default="paper")
    p.add_argument(
        "--zero-shot",
        action="store_true",
        help="with --features measurable: no fit, only the shipped model and the UKF",
    )
    p.add_argument(
        "--identify",
        type=float,
        metavar="MINUTES",
        help="with --features measurable: also score the shipped model and the UKF with "
        "the axles identified from this many minutes of the car's own labelled driving",
    )
    p.add_argument(
        "--exact",
        action="store_true",
        help="with --features measurable: also train the yardstick on the car's exact "
        "simulation (true files) and report fit / exact",
    )
    # sideslip-evaluate's; an existing fit and yardstick are re-scored, not trained again.
    add_mirror_average_argument(p, "every model")
    args = p.parse_args(argv)
    if args.exact and (args.features != "measurable" or args.zero_shot):
        p.error("--exact needs --features measurable and a fit (no --zero-shot)")
    if args.zero_shot and args.features != "measurable":
        p.error("--zero-shot needs --features measurable")
    if args.identify is not None and args.features != "measurable":
        p.error("--identify needs --features measurable")
    if args.features == "measurable":
        return measurable(args)
    cars = held_out_vehicles()
    results = {}
    for name in args.cars or list(cars):
        car, work = cars[name], args.out / name
        try:
            bags, _desc, fit, fit_s = fit_car(args, name, car, work)
        except _Failed as failed:
            return failed.code
        try:
            exact = train_exact(
                args, car, work, ["--profile", PROFILE.train_profile, "--init", SHIPPED_PAPER]
            )
        except _Failed as failed:
            return failed.code
        report = work / "report"
        code = evaluate_main(["--model", str(fit), str(exact), str(resolve(SHIPPED_PAPER)),
                              "--data", *bags, "--out", str(report), "--force",
                              "--mirror-average", args.mirror_average,
                              "--title", f"{name}: fit vs exact simulation"])  # fmt: skip
        if code:
            return code
        mae = pooled_mae(report, ["fit", "exact", SHIPPED_PAPER])
        results[name] = {
            "mae_deg": mae,
            "fit_over_exact": mae["fit"] / mae["exact"],
            "fit_wall_s": round(fit_s, 1),
        }
        print(f"{name}: {results[name]}", file=sys.stderr)
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    lines = [
        "| car | fit (description) | exact simulation | zero-shot fleet_lstm_paper | fit / exact |",
        "|---|---|---|---|---|",
    ]
    for name, r in results.items():
        m = r["mae_deg"]
        lines.append(
            f"| {name} | {m['fit']:.4f} | {m['exact']:.4f} | {m[SHIPPED_PAPER]:.4f} | "
            f"{r['fit_over_exact']:.2f} |"
        )
    (args.out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


def identified(args: argparse.Namespace, name: str, desc: Path) -> Path:
    """The ``ukf`` file ``sideslip-identify-axles`` makes from the description ``desc``
    and ``args.identify`` minutes of the car's own runs (generated once, then reused)."""
    from held_out_curve import write_own_minutes

    work = args.out / name
    out = work / f"identified-{args.identify:g}min.ukf.yaml"
    if out.exists():
        return out
    own = work / f"own-{args.identify:g}min"
    write_own_minutes(held_out_vehicles()[name], args.identify, OWN_SEED, own,
                      "held-out-own (yardstick only)", jobs=2)  # fmt: skip
    code = identify_main(["--vehicle", str(desc), "--data", str(own), "--out", str(out)])
    if code:
        raise _Failed(code)
    return out


def measurable(args: argparse.Namespace) -> int:
    """The ``--features measurable`` table (see the module)."""
    cars = held_out_vehicles()
    results = {}
    for name in args.cars or list(cars):
        car, work = cars[name], args.out / name
        try:
            bags, desc, fit, fit_s = fit_car(args, name, car, work)
            ident = None if args.identify is None else identified(args, name, desc)
            exact = train_exact(args, car, work, MEASURABLE_RECIPE) if args.exact else None
        except _Failed as failed:
            return failed.code
        described = fit.with_suffix(".ukf.yaml")
        true_file = write_true_ukf(car, work / "true.ukf.yaml", "held_out_fit.py")
        shipped = str(resolve(SHIPPED_MEASURABLE))
        mae = {}
        fitted = [] if args.zero_shot else [str(fit)]
        for tag, models, files in (
            ("described", [*fitted, shipped], observer_file_args(desc, described)),
            ("true", [*([] if exact is None else [str(exact)]), shipped],
             ["--ukf-params", str(true_file)]),
            *([] if ident is None else [
                ("identified", [shipped], observer_file_args(desc, ident))]),
        ):  # fmt: skip
            report = work / f"report-{tag}"
            code = evaluate_main(["--model", *models, "--data", *bags, "--out", str(report),
                                  "--force", "--title", f"{name}: {tag} car files",
                                  "--mirror-average", args.mirror_average,
                                  *files])  # fmt: skip
            if code:
                return code
            got = pooled_mae(report, ["fit", "exact", SHIPPED_MEASURABLE], lone=SHIPPED_MEASURABLE)
            mae.update({f"{k} [{tag}]": v for k, v in got.items()})
        results[name] = {"mae_deg": mae, "fit_wall_s": round(fit_s, 1)}
        if exact is not None:
            results[name]["fit_over_exact"] = mae["fit [described]"] / mae["exact [true]"]
        print(f"{name}: {results[name]}", file=sys.stderr)
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    cols = [
        *([] if args.zero_shot else [("fit (description)", "fit [described]")]),
        *([] if not args.exact else [("exact simulation, true car", "exact [true]")]),
        ("zero-shot, described car", f"{SHIPPED_MEASURABLE} [described]"),
        ("UKF, described car", "UKF [described]"),
        ("zero-shot, true car", f"{SHIPPED_MEASURABLE} [true]"),
        ("UKF, true car", "UKF [true]"),
        *(
            []
            if args.identify is None
            else [
                ("zero-shot, identified axles", f"{SHIPPED_MEASURABLE} [identified]"),
                ("UKF, identified axles", "UKF [identified]"),
            ]
        ),
    ]
    heads = [c for c, _ in cols] + (["fit / exact"] if args.exact else [])
    lines = ["| car | " + " | ".join(heads) + " |", "|---" * (len(heads) + 1) + "|"]
    for name, r in results.items():
        m = r["mae_deg"]
        ratio = [f"{r['fit_over_exact']:.2f}"] if args.exact else []
        cells = [*(f"{m[k]:.4f}" for _, k in cols), *ratio]
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    (args.out / "table.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
