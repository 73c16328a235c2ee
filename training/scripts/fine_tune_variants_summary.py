"""The variants table of docs/evaluation/fine-tune-folds: per validation car the pooled
MAE [deg] of ``fine_tune_variants.sh``'s models beside ``fine_tune_folds.sh``'s (D1
zero-shot, ``--folds 5`` at 3e-4, scratch), and each variant's ratio to scratch.

    python training/scripts/fine_tune_variants_summary.py data/ftvar data/cvcurve --out F
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

VARIANTS = ("ftcv", "lr1e-3", "e40", "ensemble", "ensemble_zero_shot")


def pooled(score: Path) -> dict[str, float]:
    """Model file stem -> pooled MAE [deg] in one crossfall_training_check output."""
    return {
        Path(model).stem: next(iter(by_data.values()))["pooled_mae_deg"]
        for model, by_data in json.loads(score.read_text()).items()
    }


def car_row(variants: Path, folds: Path, car: int) -> dict[str, object] | None:
    base = folds / f"cvscore-car{car}.json"
    if not base.exists():
        return None
    row: dict[str, object] = {"car": f"fleet2_car{car:03d}"}
    for stem, mae in pooled(base).items():
        label = stem.removeprefix(f"car{car}-")
        if label in ("ftcv", "scratch"):
            row[label] = mae
        elif not stem.startswith(f"car{car}-"):
            row["zero_shot"] = mae
    for score in sorted(variants.glob(f"score-car{car}-*.json")):
        for stem, mae in pooled(score).items():
            label = stem.removeprefix(f"car{car}-")
            row["ensemble_zero_shot" if stem == "fleet_ukf_ensemble_disturbance" else label] = mae
    for name in ("lr1e-3", "e40", "ensemble"):
        metrics = variants / f"car{car}-{name}.run" / "metrics.json"
        if metrics.exists():
            row[f"{name}_epochs"] = json.loads(metrics.read_text())["best_epoch"]
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("variants", type=Path, help="fine_tune_variants.sh's output folder")
    p.add_argument("folds", type=Path, help="fine_tune_folds.sh's output folder")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    rows = [r for c in range(25) if (r := car_row(args.variants, args.folds, c)) is not None]
    summary: dict[str, object] = {"cars": rows}
    for name in VARIANTS:
        have = [r for r in rows if name in r]
        if not have:
            continue
        summary[name] = {
            "cars": [r["car"] for r in have],
            "mean_mae_deg": statistics.fmean(float(r[name]) for r in have),  # type: ignore[arg-type]
            "mean_scratch_deg": statistics.fmean(float(r["scratch"]) for r in have),  # type: ignore[arg-type]
            "mean_ftcv_deg": statistics.fmean(float(r["ftcv"]) for r in have),  # type: ignore[arg-type]
        }
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    for name in VARIANTS:
        s = summary.get(name)
        if isinstance(s, dict):
            over = 1 - s["mean_mae_deg"] / s["mean_scratch_deg"]
            cars, mae = len(s["cars"]), s["mean_mae_deg"]
            print(f"{name:20s} {cars} cars  {mae:.4f}  over scratch {over:+.1%}")


if __name__ == "__main__":
    main()
