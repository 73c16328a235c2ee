"""``sideslip-fit --bags`` on validation-fleet cars: the one command a user with labelled
recordings runs, scored on the card's own test part and on other drives of the car.

For each chosen car of the validation fleet (``sideslip-generate --preset fleet --count
100 --seed 2``, never trained on; its bags in ``--val-data``): ``--minutes`` of its own
fleet-style driving (seed 4000 + car index, the seeds the axle identification was chosen
on), its description, then

    sideslip-fit --vehicle DESC --bags OWN --features measurable --out CAR.safetensors

and, beside the card's figures (each recording's last 30 %), the fitted model, the shipped
``fleet_ukf_measurable`` and the UKF with the identified and the described file on the
car's four validation-fleet runs (other manoeuvres, roads and speeds: new drives).
Writes ``OUT/summary.json`` and prints a markdown table.

    python training/scripts/fit_bags_check.py --cars 0 1 2 3 --out data/fit-bags-check

``--held-out``: the six held-out cars instead (``--cars`` indexes them in
``sideslip_sim.held_out`` order), their own driving with the learning curve's seed (7,
``held_out_curve.py``), scored on their 18 benchmark runs each (``--val-data
data/held-out``). A held-out car is scored so once; nothing is chosen on it.

``--as-recordings``: the owner's bags as a real car's recordings are: the same samples,
their run metadata only a generator name that is not the simulator's (no car, manoeuvre
or road). The fit then learns from recordings (``provenance["recordings"]`` > 0), so the
node's default runs the fitted network alone while it averages the shipped start with
its mirror image, as for a user's real car (the handover and the scores compare them so).

``--own-peak-ay A``: the owner who never drove near the limit. Only the own runs whose
peak |a_y| stays at or under A m/s² are given to the fit (``OUT/CAR/own`` then links to
those bags of ``OUT/CAR/own-all``); the new drives are the same.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import yaml

from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests, held_out_vehicles
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.fit import default_start
from sideslip_training.fit import main as fit_main
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from held_out_curve import made_from, write_own_minutes
from held_out_fit import description

VAL_SEED = 2
VAL_CARS = 25
OWN_SEED = 4000
HELD_OUT_OWN_SEED = 7  # held_out_curve.py's default seed


EMULATED_RECORDING = "emulated recording (fit_bags_check.py --as-recordings)"


def as_recordings(folder: Path) -> None:
    """Rewrite every bag of ``folder`` (in place) with run metadata that names
    :data:`EMULATED_RECORDING` as generator and nothing else."""
    from sideslip_msgs_py.bag import read_bag, write_bag
    from sideslip_msgs_py.sample import SensorNoiseSigma

    for bag in sorted(b for b in folder.iterdir() if b.is_dir()):
        contents = read_bag(bag)
        sigma = SensorNoiseSigma(**contents.run_metadata["noise_sigma"])
        write_bag(bag, contents.samples, sigma=sigma, force=True,
                  run_metadata={"generator": EMULATED_RECORDING})  # fmt: skip


def pooled(report: Path) -> dict[str, float]:
    summary = json.loads((report / "metrics.json").read_text())
    return {r["estimator"]: r["mae"] for r in summary["pooled"] if r["mae"] is not None}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=int, nargs="+", required=True, help="validation car indices")
    p.add_argument("--minutes", type=float, default=7.5, help="own driving per car")
    p.add_argument("--val-data", type=Path, default=Path("data/fleet-val"))
    p.add_argument("--out", type=Path, default=Path("data/fit-bags-check"))
    p.add_argument("--fit-args", default="", help="more sideslip-fit options")
    p.add_argument("--held-out", action="store_true", help="the six held-out cars (see above)")
    p.add_argument("--own-peak-ay", type=float, default=None, help="keep gentle own runs only")
    p.add_argument("--as-recordings", action="store_true", help="own bags as recordings (above)")
    p.add_argument(
        "--start",
        default=default_start("measurable", bags=True),
        help="the model sideslip-fit fine-tunes (--init; default sideslip-fit's own) and the "
        "zero-shot one scored beside it",
    )
    args = p.parse_args(argv)
    if args.held_out:
        cars = list(held_out_vehicles().values())
    else:
        cars = sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
    results = {}
    for k in args.cars:
        car = cars[k]
        work = args.out / car.name
        own = work / "own"
        generated = own if args.own_peak_ay is None else work / "own-all"
        seed = HELD_OUT_OWN_SEED if args.held_out else OWN_SEED + k
        if write_own_minutes(car, args.minutes, seed, generated, "own driving") and (
            args.as_recordings
        ):
            as_recordings(generated)
        if args.own_peak_ay is not None and not own.exists():
            own.mkdir()
            for r in json.loads((generated / "index.json").read_text())["runs"]:
                if r["peak_abs_ay_mps2"] <= args.own_peak_ay:
                    (own / r["bag"]).symlink_to((generated / r["bag"]).resolve())
        desc = work / "description.yaml"
        desc.write_text(yaml.safe_dump(description(car), sort_keys=False))
        out = work / "fitted.safetensors"
        started = time.perf_counter()
        origin = made_from(out) if out.exists() else None
        if origin is not None and origin != resolve(args.start).name:
            print(f"{out} was fitted from {origin}, not {args.start}: use another --out")
            return 2
        if not out.exists():
            code = fit_main(["--vehicle", str(desc), "--bags", str(own), "--features",
                             "measurable", "--out", str(out), "--quiet",
                             "--init", args.start, *args.fit_args.split()])  # fmt: skip
            if code != 0:
                return code
        seconds = time.perf_counter() - started
        card = pooled(work / "fitted.fit" / "report")
        ukf = out.with_suffix(".ukf.yaml")
        described = work / "fitted.fit" / "described.ukf.yaml"
        val_bags = sorted(str(b) for b in args.val_data.glob(f"{car.name}_*"))
        files = ["--vehicle", str(desc), "--observer-params", str(ukf), "--car", "given"]
        scores = {}
        for tag, ukf_params in (("identified", ukf), ("described", described)):
            report = work / f"new-drives-{tag}"
            code = evaluate_main(
                ["--model", str(out), str(resolve(args.start)), "--data", *val_bags,
                 "--out", str(report), "--force", "--ukf-params", str(ukf_params), *files]
            )  # fmt: skip
            if code != 0:
                return code
            scores[tag] = pooled(report)
            rows = json.loads((report / "metrics.json").read_text())["model_estimators"]
            # One name per model whatever the labels: the fit and its start.
            for name, path in (("fitted", out), ("start", resolve(args.start))):
                scores[tag][f"model: {name}"] = scores[tag][rows[str(path)]]
        new = scores["identified"]
        results[car.name] = {
            "seconds": seconds,
            "card": card,
            "new_drives": {**new, "UKF (described axles)": scores["described"]["UKF"]},
        }
    (args.out / "summary.json").write_text(json.dumps(results, indent=2) + "\n")
    start = resolve(args.start).stem
    print(f"| car | where | fitted | {start} | UKF identified | UKF described |")
    print("|---|---|---|---|---|---|")
    for name, r in results.items():
        for where in ("card", "new_drives"):
            m = r[where]
            fitted = m.get("model: fitted") or next(v for k, v in m.items() if "(fitted)" in k)
            shipped = m.get("model: start") or next(v for k, v in m.items() if f"({start})" in k)
            ident = m.get("UKF (identified axles)", m.get("UKF"))
            print(f"| {name} | {where} | {fitted:.4f} | {shipped:.4f} | {ident:.4f} | "
                  f"{m['UKF (described axles)']:.4f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
