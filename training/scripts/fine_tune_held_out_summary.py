"""The held-out table of docs/evaluation/fine-tune-folds: per held-out car the pooled MAE
[deg] on its 18 benchmark drives of D1 zero-shot, the ``--folds 5`` fine-tune and the
network trained from scratch on the same five minutes (``fine_tune_folds_held_out.sh``),
the epochs the folds chose and the fine-tune's ratios to scratch and zero-shot.

    python training/scripts/fine_tune_held_out_summary.py data/cvheld --out F
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from sideslip_sim.held_out import HELD_OUT_NAMES

sys.path.insert(0, str(Path(__file__).parent))
from fine_tune_variants_summary import pooled


def car_row(folder: Path, name: str) -> dict[str, object] | None:
    """One car's row, or None when its score is not there yet."""
    score = folder / f"score-{name}.json"
    if not score.exists():
        return None
    row: dict[str, object] = {"car": name}
    for stem, mae in pooled(score).items():
        label = stem.removeprefix(f"{name}-")
        row[label if label in ("ftcv", "scratch") else "zero_shot"] = mae
    metrics = json.loads((folder / f"{name}-ftcv.run" / "metrics.json").read_text())
    row["ftcv_epochs"] = metrics["cross_validation"]["epochs"]
    row["ftcv_kept_start"] = metrics["cross_validation"]["kept_start"]
    row["ftcv_over_scratch"] = 1 - float(row["ftcv"]) / float(row["scratch"])  # type: ignore[arg-type]
    row["ftcv_over_zero_shot"] = 1 - float(row["ftcv"]) / float(row["zero_shot"])  # type: ignore[arg-type]
    return row


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("folder", type=Path, help="fine_tune_folds_held_out.sh's output folder")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    rows = [r for n in HELD_OUT_NAMES if (r := car_row(args.folder, n)) is not None]
    means = {
        k: statistics.fmean(float(r[k]) for r in rows)  # type: ignore[arg-type]
        for k in ("zero_shot", "ftcv", "scratch", "ftcv_over_scratch", "ftcv_over_zero_shot")
    }
    summary = {
        "cars": rows,
        "mean_mae_deg": {k: means[k] for k in ("zero_shot", "ftcv", "scratch")},
        "ftcv_over_scratch_of_means": 1 - means["ftcv"] / means["scratch"],
        "ftcv_over_zero_shot_of_means": 1 - means["ftcv"] / means["zero_shot"],
        "mean_of_ratios": {k: means[k] for k in ("ftcv_over_scratch", "ftcv_over_zero_shot")},
    }
    args.out.write_text(json.dumps(summary, indent=2) + "\n")
    for r in rows:
        print(
            f"{r['car']:22s} zero-shot {r['zero_shot']:.4f}  ftcv {r['ftcv']:.4f} "
            f"({r['ftcv_epochs']})  scratch {r['scratch']:.4f}  "
            f"over scratch {r['ftcv_over_scratch']:+.1%}  "
            f"over zero-shot {r['ftcv_over_zero_shot']:+.1%}"
        )
    m = summary["mean_mae_deg"]
    print(
        f"mean ({len(rows)} cars): zero-shot {m['zero_shot']:.4f}  ftcv {m['ftcv']:.4f}  "
        f"scratch {m['scratch']:.4f}  over scratch {summary['ftcv_over_scratch_of_means']:+.1%}"
    )


if __name__ == "__main__":
    main()
