"""The learning curve's models (``held_out_curve.py`` work folders) on the held-out
benchmark drives **and their mirror images**, alone and averaged with their mirror image.

``held_out_curve.py`` scores the fine-tuned, scratch and zero-shot models on each car's
18 benchmark drives as generated, the way ``sideslip-evaluate`` runs them by default
(each model that learnt from simulated runs only averaged with its mirror image). The
drives as generated start to the side the fleet's training drives did, which favours a
network alone (docs/evaluation/direction). Here each model is scored on the drives and
on each drive's mirror image (the same drive the other way round), pooled MAE [deg]:

- ``deployed``: as the node's default runs the file (``pso_lstm.mirror_average: auto``);
- ``alone`` / ``averaged``: each way, whatever the file records;
- ``alone one way``: the drives as generated only, the network alone (the figures of
  the learning-curve tables before 2026-12-06).

The car files are the user's (``--identified``: the description and the axles
identified from the same minutes, ``--car given``). The averaged estimate is half the
difference of the network alone on a drive and on its mirror image, as in
``fit_bags_handover.py``. Writes ``--out`` (JSON) and prints a markdown table.

    python training/scripts/held_out_curve_both_ways.py --work data/held-out-curve-avg/*-s7 \\
        --identified data/hofm-ident2 --out FILE.json
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from sideslip_msgs_py.data_source import mirror_average_on
from sideslip_msgs_py.mirror import mirrored
from sideslip_msgs_py.vehicle_description import VehicleDescription
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import evaluate_runs
from sideslip_training.export import load_model
from sideslip_training.init_model import resolve
from sideslip_training.training_data import MIRROR_SUFFIX

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_handover import maes

KINDS = ("finetuned", "scratch", "zero_shot")
FORMS = ("deployed", "alone", "averaged", "alone one way")


def car_of(work: Path) -> str:
    """The held-out car of a ``held_out_curve.py`` work folder (``CAR-BASE-TAG``)."""
    return work.name.split("-")[0]


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", nargs="+", type=Path, required=True, help="CAR-measurable-TAG")
    p.add_argument("--held-out", type=Path, default=Path("data/held-out"))
    p.add_argument("--identified", type=Path, required=True, help="held_out_fit.py --identify")
    p.add_argument("--minutes", default="5")
    p.add_argument("--start", default="fleet_ukf_ensemble")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    summary: dict[str, dict[str, dict[str, float]]] = {}
    for work in args.work:
        car = car_of(work)
        files = {
            "finetuned": work / f"finetuned_{args.minutes}min.safetensors",
            "scratch": work / f"scratch_{args.minutes}min.safetensors",
            "zero_shot": resolve(args.start),
        }
        missing = [str(f) for f in files.values() if not f.exists()]
        if missing:  # a --no-scratch folder has no scratch model to compare
            raise SystemExit(f"{work.name}: missing {', '.join(missing)}")
        models = {k: load_model(f) for k, f in files.items()}
        meta = models["finetuned"][1]
        drives = sorted(args.held_out.glob(f"{car}_mu*"))
        if len(drives) != 18:
            raise SystemExit(f"{car}: expected 18 held-out drives, got {len(drives)}")
        runs, _ = load_runs(drives, step_s=meta.dt_s)
        both = [*runs, *(replace(r, name=r.name + MIRROR_SUFFIX, samples=mirrored(r.samples))
                         for r in runs)]  # fmt: skip
        ident = args.identified / car
        traces = evaluate_runs(
            both,
            [(k, *m) for k, m in models.items()],
            window_steps=meta.window_steps,
            dt_s=meta.dt_s,
            vehicle=VehicleDescription.load(ident / "description.yaml"),
            observer_params_file=str(ident / f"identified-{args.minutes}min.ukf.yaml"),
            car="given",
            mirror_average=False,
        )
        row: dict[str, dict[str, float]] = {}
        for kind, (_, m) in models.items():
            got = {k.removeprefix(f"{kind} "): v for k, v in maes(traces, kind).items()}
            averaged = mirror_average_on("auto", m.provenance)
            got["deployed"] = got["averaged" if averaged else "alone"]
            row[kind] = got
        summary[work.name] = row
        print(work.name, json.dumps(row), flush=True)
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    heads = [f"{k} {f}" for f in FORMS for k in KINDS]
    print("| work | " + " | ".join(heads) + " |")
    print("|---|" + "---|" * len(heads))
    for name, r in summary.items():
        cells = [f"{r[k][f]:.4f}" for f in FORMS for k in KINDS]
        print(f"| {name} | " + " | ".join(cells) + " |")
    for f in FORMS:
        ft, sc, zs = (float(np.mean([r[k][f] for r in summary.values()])) for k in KINDS)
        print(f"{f}: fine-tuned {ft:.4f}, scratch {sc:.4f}, zero-shot {zs:.4f}; "
              f"vs scratch {1 - ft / sc:+.1%}, vs zero-shot {1 - ft / zs:+.1%}")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
