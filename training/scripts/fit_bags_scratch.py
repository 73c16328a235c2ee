"""Issue 9's comparison for the one-command path: the model ``sideslip-fit --bags`` fine-
tuned against the same network trained from scratch on the same recordings, and the
shipped model zero-shot.

For each car folder of ``fit_bags_check.py`` (its own driving in ``own/``, the
description, the identified ``fitted.ukf.yaml`` and the fine-tuning's
``fitted.fit/train-run/config.json``): the fine-tuning's own ``sideslip-train`` command
with ``--init fleet_ukf_measurable`` replaced by the shipped model's recipe from random
weights (``--model lstm --hidden-units 64 --features measurable_observer_signals --prior
ukf``, as ``held_out_curve.py --base measurable``): same recordings, split, profile,
stride, seed and car files. Then the three are scored on the car's drives in ``--drives``
(for the held-out cars their 18 benchmark runs) with the identified file, and on the
card's test part (each recording's last 30 %, from the training runs' metrics).

    python training/scripts/fit_bags_scratch.py --cars data/fit-bags-held-out/heldout_* \
        --drives data/held-out --out scratch.json
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys
from pathlib import Path

from sideslip_training.cli import train_main
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.init_model import resolve

SHIPPED = "fleet_ukf_measurable"
SCRATCH = ["--model", "lstm", "--hidden-units", "64", "--features",
           "measurable_observer_signals", "--prior", "ukf"]  # fmt: skip


def scratch_command(fine_tuning: str, out: Path) -> list[str]:
    """The fine-tuning's ``sideslip-train`` arguments, from random weights into ``out``."""
    argv = shlex.split(fine_tuning)[1:]
    i = argv.index("--init")
    del argv[i : i + 2]
    for flag, value in (("--out", str(out)), ("--run-dir", str(out.with_suffix(".run")))):
        argv[argv.index(flag) + 1] = value
    return [*argv, *SCRATCH]


def pooled(report: Path) -> dict[str, dict[str, float]]:
    rows = json.loads((report / "metrics.json").read_text())["pooled"]
    return {r["estimator"]: r for r in rows if r["mae"] is not None}


def pick(rows: dict, stem: str) -> dict:
    return next(v for k, v in rows.items() if k.endswith(f"({stem})"))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--cars", type=Path, nargs="+", required=True, help="fit_bags_check folders")
    p.add_argument("--drives", type=Path, required=True, help="folder of the cars' other runs")
    p.add_argument("--out", type=Path, required=True, help="JSON of the results")
    args = p.parse_args(argv)
    results = {}
    for car in sorted(args.cars):
        scratch = car / "scratch.safetensors"
        fitted = car / "fitted.safetensors"
        if not scratch.exists():
            config = json.loads((car / "fitted.fit/train-run/config.json").read_text())
            code = train_main(scratch_command(config["command"], scratch))
            if code != 0:
                return code
        ukf = car / "fitted.ukf.yaml"
        drives = sorted(str(b) for b in args.drives.glob(f"{car.name}_*"))
        report = car / "scratch-new-drives"
        code = evaluate_main(
            ["--model", str(fitted), str(scratch), str(resolve(SHIPPED)), "--data", *drives,
             "--out", str(report), "--force", "--ukf-params", str(ukf), "--vehicle",
             str(car / "description.yaml"), "--observer-params", str(ukf), "--car", "given"]
        )  # fmt: skip
        if code != 0:
            return code
        rows = pooled(report)
        test = {
            kind: next(
                v["mae_deg"]
                for k, v in json.loads((run / "metrics.json").read_text())["test"].items()
                if k.startswith("LSTM")
            )
            for kind, run in (("fitted", car / "fitted.fit/train-run"),
                              ("scratch", scratch.with_suffix(".run")))
        }  # fmt: skip
        results[car.name] = {
            "drives": {
                "fitted": pick(rows, "fitted")["mae"],
                "scratch": pick(rows, "scratch")["mae"],
                "shipped": pick(rows, SHIPPED)["mae"],
                "UKF": rows["UKF"]["mae"],
            },
            "test_part": test,
        }
    args.out.write_text(json.dumps(results, indent=2) + "\n")
    print("| car | drives: fitted | scratch | shipped | fitted vs scratch | test part: fitted "
          "| scratch |\n|---|---|---|---|---|---|---|")  # fmt: skip
    for name, r in results.items():
        d, t = r["drives"], r["test_part"]
        gain = 1.0 - d["fitted"] / d["scratch"]
        print(f"| {name} | {d['fitted']:.4f} | {d['scratch']:.4f} | {d['shipped']:.4f} | "
              f"{gain:+.0%} | {t['fitted']:.4f} | {t['scratch']:.4f} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
