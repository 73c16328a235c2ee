"""The table of docs/evaluation/fine-tune-folds from ``fine_tune_folds.sh``'s outputs:
per validation car the pooled MAE [deg] of the start (zero-shot), the fine-tune chosen
on the validation split and by --folds, and scratch; the epochs each chose.

    python training/scripts/fine_tune_folds_summary.py data/cvcurve --out summary.json
"""

from __future__ import annotations

import argparse
import json
import statistics
from pathlib import Path

LABELS = ("ft", "ftcv", "scratch", "scratchcv")


def car_row(folder: Path, car: int) -> dict[str, object] | None:
    score = folder / f"cvscore-car{car}.json"
    if not score.exists():
        return None
    row: dict[str, object] = {"car": f"fleet2_car{car:03d}"}
    for path, by_data in json.loads(score.read_text()).items():
        label = Path(path).stem.removeprefix(f"car{car}-")
        label = label if label in LABELS else "zero_shot"
        row[label] = next(iter(by_data.values()))["pooled_mae_deg"]
    for label in ("ft", "scratch"):
        metrics = folder / f"car{car}-{label}.run" / "metrics.json"
        row[f"{label}_best_epoch"] = json.loads(metrics.read_text())["best_epoch"]
    for label in ("ftcv", "scratchcv"):
        cv = folder / f"car{car}-{label}.run" / "cross_validation.json"
        if cv.exists():
            row[f"{label}_epochs"] = json.loads(cv.read_text())["epochs"]
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", type=Path)
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    rows = [r for c in range(25) if (r := car_row(args.folder, c)) is not None]
    rows = [r for r in rows if all(k in r for k in ("zero_shot", "ft", "ftcv", "scratch"))]
    mean = {
        k: statistics.fmean(float(r[k]) for r in rows)  # type: ignore[arg-type]
        for k in ("zero_shot", "ft", "ftcv", "scratch")
    }

    def ratio(a: str, b: str) -> list[float]:
        return [float(r[a]) / float(r[b]) for r in rows]  # type: ignore[arg-type]

    ratios = {
        "ftcv_over_scratch": ratio("ftcv", "scratch"),
        "ftcv_over_zero_shot": ratio("ftcv", "zero_shot"),
        "ftcv_over_ft": ratio("ftcv", "ft"),
    }
    mean |= {f"mean_of_{k}": statistics.fmean(v) for k, v in ratios.items()}
    out = {"cars": rows, "mean_mae_deg": mean, "ratios": ratios}
    args.out.write_text(json.dumps(out, indent=2) + "\n")
    print(
        json.dumps(
            {"mean_mae_deg": mean, **{k: [round(x, 2) for x in v] for k, v in ratios.items()}}
        )
    )


if __name__ == "__main__":
    main()
