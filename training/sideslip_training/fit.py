"""``sideslip-fit``: from a car's short description to a model fitted to it.

(With ``--bags``, from the car's own labelled recordings instead: :mod:`.fit_bags`.)

What an owner can look up (a description YAML: mass, wheelbase, CG position, CG height,
track, steering ratio as rack travel per road-wheel radian, tyre radius; optionally
``drive_layout``) becomes a fleet of simulated cars around it: those values within a
few per cent, everything unknown (inertia, tyres, suspension, understeer) spread as in
the fleet, μ 0.3–1.0 (:func:`sideslip_sim.fleet.centred_ranges`). One more car from the
same ranges is kept aside as "your car" for the test. Then:

1. generate the fleet's runs (training) and the test car's runs (other manoeuvres);
2. train: ``paper`` features fine-tune the shipped ``fleet_lstm_paper`` (``--init``);
   ``measurable`` ones (no Y_v) fine-tune ``fleet_ukf_described``, a residual on the
   UKF. The node can only give that UKF the parameters the description implies (the
   described car, :mod:`sideslip_sim.described_car`: the fleet's typical tyres, inertia
   and balance for what is unknown), so the training runs the UKF with those too
   (``--car given``), not with each simulated car's true parameters: the network learns
   to correct the filter the node will run. That ``ukf`` params file is written next to
   the model (``OUT`` with ``.ukf.yaml``);
3. evaluate the fitted model beside the zero-shot fleet model and the baselines on the
   test car's runs (``measurable``: all with the described car's files, the UKF too);
4. write the model card (``OUT`` with ``.md``) next to the model.

The work folder (default ``OUT`` + ``.fit``) keeps the data: a second call with the
same description and options reuses it (resumable); ``--force`` starts over.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from .car_description import Description
from .cli_errors import EXIT_BAD_INPUT, CliError
from .fit_bags import stage
from .fit_bags_args import BAG_RECIPES, add_bag_arguments, check_bag_arguments

SHIPPED_PAPER: Final = "fleet_lstm_paper"
SHIPPED_MEASURABLE: Final = "fleet_ukf_measurable"
SHIPPED_DESCRIBED: Final = "fleet_ukf_described"
"""The start of a ``measurable`` fit from a description alone: trained with the UKF on
each bag's true or described car, half and half (``sideslip-train --car mixed``), it
corrects a described car's filter better than ``fleet_ukf_measurable``, which only ever
saw true files (fits from it on 16 validation cars: 0.048° against 0.056°, better on
12; docs/training.md). With recordings (``--bags``) the axles are identified, the
filter is nearly right, and the fit starts from :data:`SHIPPED_BAGS`."""
SHIPPED_BAGS: Final = "fleet_ukf_ensemble"
"""The start of a ``measurable`` fit to recordings: five networks averaged in one file,
fine-tuned member by member (``sideslip-train --init-members keep``). Chosen on eight
validation cars, 5 minutes of each one's driving, scored on their 18 benchmark-style
drives: fitted from it (0.25 of the way) 0.0283° against 0.0290° from
``fleet_ukf_merged``, the start before 2026-12-05 (better on 7 of 8);
docs/models/fleet_ukf_ensemble/finetune-start-validation.json. Before, the pair had
replaced ``fleet_ukf_measurable`` the same way (0.0300° against 0.0317° on four cars;
docs/models/fleet_ukf_merged)."""
SHIPPED: Final = {"paper": SHIPPED_PAPER, "measurable": SHIPPED_MEASURABLE}


def default_start(features: str, bags: bool) -> str:
    """The shipped model a fit fine-tunes when ``--init`` is not given."""
    if features == "measurable":
        return SHIPPED_BAGS if bags else SHIPPED_DESCRIBED
    return SHIPPED[features]


@dataclass(frozen=True)
class FitProfile:
    """How much simulated driving a fit gets."""

    cars: int
    test_runs: int
    train_profile: str
    max_epochs: int | None = None
    """Cap on the training's epochs (None: the training profile's)."""


FIT_PROFILES: Final = {
    # ~48 training runs (~7 min of driving): minutes on 2 CPU cores; at most 30 epochs
    # (the quick training profile allows 60, which a from-scratch `measurable` fit
    # could fill at ~20 s per epoch here).
    "quick": FitProfile(cars=12, test_runs=8, train_profile="quick", max_epochs=30),
    # ~160 runs and the paper's training settings: for a GPU or an evening.
    "thorough": FitProfile(cars=40, test_runs=16, train_profile="paper"),
}


def plan_runs(desc: Description, profile: FitProfile, seed: int) -> tuple[list[Any], list[Any]]:
    """The training runs (the fleet around the car) and the test car's runs."""
    from sideslip_sim.fleet import sample_fleet
    from sideslip_sim.held_out import held_out_digests
    from sideslip_sim.presets import FLEET_RUNS_PER_CAR, VehicleRun, fleet_runs

    cars = sample_fleet(
        profile.cars + 1,
        seed,
        prefix=f"{desc.name}_fit",
        ranges=desc.ranges(),
        exclude_digests=held_out_digests(),
    ).vehicles
    # Every run turns the side it draws: a fleet whose scripted manoeuvres all open to the
    # left teaches the network which way the car turns (docs/evaluation/direction).
    train = fleet_runs(cars[:-1], FLEET_RUNS_PER_CAR * profile.cars, seed, both_sides=True)
    test_car = cars[-1]
    test: list[VehicleRun] = []
    for k in range(-(-profile.test_runs // FLEET_RUNS_PER_CAR)):
        for r in fleet_runs([test_car], FLEET_RUNS_PER_CAR, seed + 1000 + k, both_sides=True):
            m = dataclasses.replace(r.maneuver, name=f"test{k}_{r.maneuver.name}")
            test.append(VehicleRun(test_car, m))
    return train, test[: profile.test_runs]


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="sideslip-fit",
        description=(
            "Fit a sideslip estimator to your car from its description: a fleet of "
            "simulated cars around it, training, a test on one more car from the same "
            "description, and a model card. Profiles: "
            + "; ".join(
                f"{k}: {v.cars} cars x 4 runs, {v.test_runs} test runs, sideslip-train "
                f"--profile {v.train_profile}"
                for k, v in FIT_PROFILES.items()
            )
            + ". With --bags, the car's own recordings with a reference β instead of the "
            "simulated fleet: measurable features identify the UKF's axles on them first; "
            "then fine-tuning ("
            + "; ".join(f"{k}: {v.summary}" for k, v in BAG_RECIPES.items())
            + ") and a test on every recording's last --test-fraction (and on --test-bags, other "
            "recordings of the car, when given)"
        ),
        epilog=(
            "The description (YAML): mass_kg (with usual payload), wheelbase_m, "
            "cg_to_front_axle_m, cg_height_m, track_m, stl_per_road_wheel_angle_m_per_rad "
            "(rack travel per road-wheel radian), tire_rolling_radius_m; optionally "
            "drive_layout (fwd, rwd, awd) and name."
        ),
    )
    p.add_argument("--vehicle", required=True, type=Path, help="the car's description (YAML)")
    p.add_argument("--out", required=True, type=Path, metavar="FILE.safetensors")
    p.add_argument(
        "--profile",
        choices=list(FIT_PROFILES),
        default="quick",
        help="quick: 12 cars around the description, at most 30 epochs (with --bags: "
        "every 10th window, no mirrored runs; 13-30 min for 7.5 min of recordings on 2 "
        "cores from the shipped start, beside another job); thorough: 40 cars and the "
        "paper's training settings (with --bags: every window, runs mirrored; 33 min for "
        "the same recordings from an earlier start, 21 %% less error on "
        "their test part on the one car measured, docs/evaluation/fit-bags)",
    )
    p.add_argument(
        "--features",
        choices=["paper", "measurable"],
        default="paper",
        help=f"paper (with Y_v): fine-tune {SHIPPED_PAPER}; measurable (no Y_v): fine-tune "
        f"{SHIPPED_DESCRIBED} ({SHIPPED_BAGS} with --bags) with the UKF run on the "
        "described car (with --bags: on the identified axles; its ukf params file "
        "is written next to OUT)",
    )
    p.add_argument(
        "--init",
        metavar="MODEL",
        help="the model to fine-tune (a shipped name or a .safetensors file; default "
        "the --features one named there); its features must be "
        "the --features set's",
    )
    p.add_argument("--cars", type=int, help="override the profile's number of cars")
    p.add_argument("--test-runs", type=int, help="override the profile's test runs")
    p.add_argument("--max-epochs", type=int, help="override the profile's cap on epochs")
    p.add_argument(
        "--learning-rate",
        type=float,
        help="override the fine-tuning's learning rate (1e-3; with --bags from "
        "fleet_ukf_ensemble 3e-4, chosen on validation cars)",
    )
    p.add_argument("--work", type=Path, help="data and reports (default: OUT + .fit)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--jobs", type=int, default=2, help="simulation processes")
    p.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    p.add_argument("--force", action="store_true", help="replace OUT and start the work over")
    p.add_argument("--quiet", action="store_true")
    add_bag_arguments(p)
    return p


def recipe_options(profile: FitProfile) -> list[str]:
    """The ``sideslip-train`` options a fit of ``profile`` trains with, besides its data,
    start model, device and seed (also the recipe of ``held_out_fit.py``'s yardstick)."""
    # The fleet around the car is simulated, drives both ways (plan_runs) and can be made
    # bigger at will: mirroring it would double the time for nothing.
    options = ["--profile", profile.train_profile, "--mirror", "no"]
    if profile.max_epochs is not None:
        options += ["--max-epochs", str(profile.max_epochs)]
    return options


def check_start(spec: str, features: str) -> None:
    """Refuse, before minutes of simulation, a start model the fit cannot fine-tune:
    ``measurable`` fits run without Y_v, ``paper`` fits without the UKF."""
    from sideslip_msgs_py.model_inputs import needs_observer, required_channels

    from .init_model import InitError, load_init

    try:
        meta = load_init(spec).meta
    except InitError as err:
        raise CliError(str(err)) from None
    if features == "measurable" and "y_v_mps" in required_channels(meta.features, meta.prior):
        raise CliError(f"--init {spec}: reads Y_v, not a measurable model (--features paper?)")
    if features == "paper" and needs_observer(meta.features, meta.prior):
        raise CliError(
            f"--init {spec}: reads the UKF's outputs, which a paper fit does not run "
            "(--features measurable?)"
        )


def main(argv: Sequence[str] | None = None) -> int:
    from sideslip_sim.generate import generate, prepare_output

    from .cli import train_main
    from .evaluate_cli import main as evaluate_main

    args = _parser().parse_args(argv)
    log = (lambda *_: None) if args.quiet else (lambda msg: print(msg, file=sys.stderr))
    started = time.perf_counter()
    try:
        if args.out.suffix != ".safetensors":
            raise CliError(f"--out {args.out}: must end in .safetensors")
        if args.out.exists() and not args.force:
            raise CliError(f"--out {args.out} exists; pass --force to replace it")
        desc = Description.load(args.vehicle)
        start = args.init or default_start(args.features, args.bags is not None)
        check_start(start, args.features)
        test_fraction = check_bag_arguments(args)
        if args.bags is not None:
            from .fit_bags import run as fit_to_bags

            return fit_to_bags(args, desc, start, test_fraction, log, started)
        profile = FIT_PROFILES[args.profile]
        for name in ("cars", "test_runs", "max_epochs"):
            value = getattr(args, name)
            if value is not None:
                if value < 1:
                    raise CliError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
                profile = dataclasses.replace(profile, **{name: value})
        work = args.work or args.out.with_suffix(".fit")
        # "sides": a work folder of the drives that opened to the left is not resumed.
        key = {"car": desc.digest(), "profile": dataclasses.asdict(profile), "seed": args.seed,
               "sides": "both"}  # fmt: skip
        stamp = work / "fit.json"
        reuse = stamp.exists() and json.loads(stamp.read_text()).get("key") == key
        if args.force or not reuse:
            shutil.rmtree(work, ignore_errors=True)
        work.mkdir(parents=True, exist_ok=True)
        stage(log, started, f"fleet around {desc.name}: {profile.cars} cars, one more for the test")
        train_runs, test_runs = plan_runs(desc, profile, args.seed)
        car_files: list[str] = []
        filters: list[str] = []
        if args.features == "measurable":
            ukf_file = args.out.with_suffix(".ukf.yaml")
            ukf_file.write_text(desc.ukf_params_yaml())
            car_files = ["--vehicle", str(args.vehicle), "--observer-params", str(ukf_file)]
            car_files += ["--car", "given"]
            filters = ["--ukf-params", str(ukf_file)]
    except CliError as err:
        print(f"sideslip-fit: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    for folder, runs in (("train", train_runs), ("test", test_runs)):
        out = work / folder
        if reuse and (out / "index.json").exists():
            stage(log, started, f"{folder}: {len(runs)} runs already generated (resumed)")
            continue
        stage(log, started, f"{folder}: simulating {len(runs)} runs")
        prepare_output(out, force=True)
        generate(runs, out, seed=args.seed, preset_name=f"fit-{folder}", jobs=args.jobs,
                 progress=not args.quiet)  # fmt: skip
    stamp.write_text(json.dumps({"key": key, "vehicle": str(args.vehicle)}) + "\n")
    stage(log, started, "training")
    common = ["--data", str(work / "train"), "--out", str(args.out), "--force"]
    common += [*recipe_options(profile), "--device", args.device]
    common += ["--seed", str(args.seed), *(["--quiet"] if args.quiet else [])]
    if args.learning_rate is not None:
        common += ["--learning-rate", repr(args.learning_rate)]
    code = train_main([*common, "--init", start, *car_files])
    if code != 0:
        return code
    stage(log, started, "evaluating on the test car")
    from .init_model import resolve

    models = [str(args.out), str(resolve(start))]
    # measurable: the UKF beside them, and every model fed the described car's files.
    report = work / "report"
    code = evaluate_main(
        ["--model", *models, "--data", str(work / "test"), "--out", str(report), "--force",
         "--title", f"{desc.name}: fitted model on the test car", *car_files, *filters]
    )  # fmt: skip
    if code != 0:
        return code
    card = _model_card(desc, args, profile, work, report, time.perf_counter() - started)
    args.out.with_suffix(".md").write_text(card)
    stage(log, started, f"wrote {args.out} and {args.out.with_suffix('.md')}")
    return 0


def _model_card(
    desc: Description,
    args: argparse.Namespace,
    profile: FitProfile,
    work: Path,
    report: Path,
    seconds: float,
) -> str:
    summary = json.loads((report / "metrics.json").read_text())
    rows = "\n".join(
        f"| {r['estimator']} | {r['mae']:.4f} | {r['rmse']:.4f} | {r['n']} |"
        for r in summary["pooled"]
        if r["mae"] is not None
    )
    nominal = "\n".join(f"- {k}: {v:g}" for k, v in desc.nominal.to_dict().items())
    ukf = args.out.with_suffix(".ukf.yaml")
    deploy = (
        f"`-p pso_lstm.model_file:={args.out} -p pso_lstm.vehicle_file:={args.vehicle} "
        f"-p pso_lstm.observer_params_file:={ukf}`. The UKF it corrects ran in training "
        f"with `{ukf}` (the described car: the fleet's typical tyres, inertia and balance "
        "for what the description does not say); give the node that file, not another."
        if args.features == "measurable"
        else f"`-p pso_lstm.model_file:={args.out}` (needs Y_v; nothing about the car)."
    )
    recorded = (
        "\n\nWithout Y_v the description is this model's limit: the UKF it corrects has the "
        "fleet's typical tyres. Recordings with a reference β measure the car's own: "
        f"`sideslip-identify-axles --vehicle {args.vehicle} --data BAGS --out my_car.ukf.yaml` "
        "fits the axles' cornering stiffness to them. Give that file to the shipped "
        "`fleet_ukf_ensemble` (trained on true axle files and on described ones), or "
        "fine-tune that model on "
        "the recordings with it (`--observer-params`), not to this model, which learnt to "
        "correct the described file (docs/training.md, \"Axles from the car's own "
        'recordings").'
        if args.features == "measurable"
        else ""
    )
    return f"""# Model card: {args.out.name}

Fitted by `sideslip-fit --vehicle {args.vehicle} --profile {args.profile} --features
{args.features}` in {seconds:.0f} s.

## The car, {desc.name}, as described

{nominal}
- drive layout: {desc.layout or "not given (drawn per car)"}

## Data

{profile.cars} simulated cars around this description (the values above within a few
per cent; inertia, tyres, suspension and understeer spread as in the fleet), four runs
each, road μ 0.3–1.0, paper sensor noise: `{work / "train"}`. Tested on
{profile.test_runs} runs of one more car drawn from the same description, never trained
on: `{work / "test"}`.

## Deploy

{deploy}

## Result on the test car (pooled over its runs, degrees)

| estimator | MAE | RMSE | samples |
|---|---|---|---|
{rows}

## Limits

Simulated data only: a real car differs from every simulated one in what the
description does not fix (tyres, bushings, sensor mounting and bias). Check the model on
a recording of the car (`sideslip-evaluate`, with `--topic-map` for your topics) before
relying on it, and fine-tune it there (`sideslip-train --init {args.out}`).{recorded}
"""


if __name__ == "__main__":
    sys.exit(main())
