"""A body-frame IMU without an attitude: how much a fixed scale on Y_a recovers, on
validation cars.

A strapdown IMU reads a_y·cos φ + g·sin φ; the body's roll φ grows with a_y (the roll
gradient), so without an attitude source the best a topic map can do is a scale,
``y_a_mps2: {..., scale: 1/(1 + κ)}``, where κ is the share of gravity in the reading
(g times the roll gradient in rad per m/s²). Two ways to get κ are scored:

- ``typical``: the median κ of other validation cars (``--calibration``: the same
  drives generated twice, ``--imu-frame level`` and ``body``), for an owner who knows
  nothing of the car's roll;
- ``own``: κ from the car's own drives without any reference: Y_a against X_v·ψ̇ over
  quasi-steady samples (|ψ̈| < 0.1 rad/s², filtered at 2 Hz), whose slope is 1 + κ for
  a level IMU up to the steady-state terms.

Every car is scored with its true ``ukf`` file, the models given and the UKF, through a
topic map over the contract topics (scale 1 for ``level`` and ``body``), pooled MAE
[deg] per car. Writes ``OUT`` (JSON), prints a table.

    python training/scripts/validation_benchmark.py --cars 0 1 2 3 4 5 6 7 \
        --out data/val-benchmark-imu-body --imu-frame body    # and 8..15 into -2
    python training/scripts/imu_frame_check.py --level data/val-benchmark \
        --body data/val-benchmark-imu-body \
        --calibration data/val-benchmark-2 data/val-benchmark-2-imu-body \
        --model fleet_ukf_ensemble --out imu-frame-validation.json
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import yaml
from scipy.signal import butter, sosfiltfilt

from sideslip_msgs_py.bag import read_bag
from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED
from held_out_fit import description, pooled_mae, write_true_ukf

CONTRACT_MAP = {
    "channels": {
        "x_a_mps2": {"topic": "/vehicle/imu", "field": "linear_acceleration.x"},
        "y_a_mps2": {"topic": "/vehicle/imu", "field": "linear_acceleration.y"},
        "yaw_rate_radps": {"topic": "/vehicle/imu", "field": "angular_velocity.z"},
        "x_v_mps": {"topic": "/vehicle/twist", "field": "twist.linear.x"},
        "y_v_mps": {"topic": "/vehicle/twist", "field": "twist.linear.y"},
        "stl_m": {"topic": "/vehicle/steering", "field": "position[steering_rack]"},
    },
    "reference": {"beta_rad": {"topic": "/vehicle/ground_truth/sideslip", "field": "data"}},
}


def bags_by_car(folder: Path) -> dict[str, list[Path]]:
    out: dict[str, list[Path]] = defaultdict(list)
    for run in json.loads((folder / "index.json").read_text())["runs"]:
        out[run["vehicle"]].append(folder / run["bag"])
    return dict(out)


def _smooth(x: np.ndarray, rate_hz: float, cutoff_hz: float = 2.0) -> np.ndarray:
    return sosfiltfilt(butter(2, cutoff_hz, fs=rate_hz, output="sos"), np.asarray(x, float))


def gravity_share_true(level: list[Path], body: list[Path]) -> float:
    """κ of a car from the same drives read level and in the body frame: the slope of
    the body reading over the level one where |a_y| > 2 m/s², minus one."""
    xs, ys = [], []
    for a, b in zip(level, body, strict=True):
        la, ba = read_bag(a).samples.y_a_mps2, read_bag(b).samples.y_a_mps2
        keep = np.abs(la) > 2.0
        xs.append(la[keep])
        ys.append(ba[keep])
    x, y = np.concatenate(xs), np.concatenate(ys)
    return float(np.dot(x, y) / np.dot(x, x) - 1.0)


def gravity_share_own(bags: list[Path]) -> float:
    """κ of a car from its own drives alone (no reference): the slope of Y_a over
    X_v·ψ̇ on quasi-steady samples, minus one (see module)."""
    xs, ys = [], []
    for bag in bags:
        s = read_bag(bag).samples
        t = (s.stamp_ns - s.stamp_ns[0]) * 1e-9
        rate = 1.0 / float(np.median(np.diff(t)))
        u, r, f_y = (_smooth(c, rate) for c in (s.x_v_mps, s.yaw_rate_radps, s.y_a_mps2))
        keep = (u > 5.0) & (np.abs(np.gradient(r, t)) < 0.1) & (np.abs(u * r) > 1.0)
        xs.append((u * r)[keep])
        ys.append(f_y[keep])
    x, y = np.concatenate(xs), np.concatenate(ys)
    return float(np.dot(x, y) / np.dot(x, x) - 1.0)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--level", type=Path, required=True, help="validation_benchmark.py folder")
    p.add_argument("--body", type=Path, required=True, help="the same drives, --imu-frame body")
    p.add_argument("--calibration", type=Path, nargs=2, required=True, metavar=("LEVEL", "BODY"),
                   help="other cars' drives, level and body, for the typical κ")  # fmt: skip
    p.add_argument("--model", nargs="+", default=["fleet_ukf_ensemble"])
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    fleet = {
        v.name: v
        for v in sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
    }
    cal_level, cal_body = (bags_by_car(f) for f in args.calibration)
    typical_cars = {c: gravity_share_true(cal_level[c], cal_body[c]) for c in sorted(cal_level)}
    typical = float(np.median(list(typical_cars.values())))
    print(f"typical κ {typical:.4f} over {len(typical_cars)} calibration cars", file=sys.stderr)
    models = [str(resolve(m)) for m in args.model]
    stems = [Path(m).stem for m in models]
    work = args.out.with_suffix(".work")
    level, body = bags_by_car(args.level), bags_by_car(args.body)
    results: dict[str, dict[str, object]] = {}
    for car in sorted(body):
        folder = work / car
        folder.mkdir(parents=True, exist_ok=True)
        true_file = write_true_ukf(fleet[car], folder / "true.ukf.yaml", "imu_frame_check.py")
        desc = folder / "description.yaml"
        desc.write_text(yaml.safe_dump(description(fleet[car]), sort_keys=False))
        # Mapped bags record no car: the node's files, the car's true ones.
        car_files = ["--vehicle", str(desc), "--observer-params", str(true_file), "--car",
                     "given", "--ukf-params", str(true_file)]  # fmt: skip
        kappa = {"true": gravity_share_true(level[car], body[car]),
                 "own": gravity_share_own(body[car])}  # fmt: skip
        row: dict[str, object] = {"kappa": kappa}
        for variant, bags, scale in (
            ("level", level[car], 1.0),
            ("body", body[car], 1.0),
            ("body, typical scale", body[car], 1.0 / (1.0 + typical)),
            ("body, own scale", body[car], 1.0 / (1.0 + kappa["own"])),
        ):
            spec = json.loads(json.dumps(CONTRACT_MAP))
            spec["channels"]["y_a_mps2"]["scale"] = scale
            topic_map = folder / f"{variant.replace(', ', '-').replace(' ', '_')}.yaml"
            topic_map.write_text(yaml.safe_dump(spec, sort_keys=False))
            report = topic_map.with_suffix(".report")
            code = evaluate_main(["--model", *models, "--data", *map(str, bags), "--out",
                                  str(report), "--force", "--topic-map", str(topic_map),
                                  *car_files])  # fmt: skip
            if code:
                return code
            lone = stems[0] if len(stems) == 1 else None
            got = pooled_mae(report, stems, lone)
            row[variant] = {k: v for k, v in got.items() if "β" not in k}
        results[car] = row
        print(car, json.dumps(row), file=sys.stderr, flush=True)
    summary = {"typical_kappa": typical, "calibration_cars": typical_cars, "cars": results}
    args.out.write_text(json.dumps(summary, indent=1) + "\n")
    variants = ("level", "body", "body, typical scale", "body, own scale")
    for key in [*stems, "UKF"]:
        means = {v: np.mean([r[v][key] for r in results.values()]) for v in variants}  # type: ignore[index]
        print(f"| {key} | " + " | ".join(f"{means[v]:.4f}" for v in variants) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
