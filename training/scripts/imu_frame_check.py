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
  a level IMU up to the steady-state terms;
- ``checked``: the scale the data report's accelerometer check gives for the car's
  drives with their reference (:mod:`sideslip_training.accelerometer_check`), for an
  owner with labelled recordings;
- ``self-calibrated``: scale and bias from the car's own drives without a reference,
  from the integrated kinematics (:mod:`sideslip_estimator.accelerometer_scale`, what
  ``sideslip-imu-scale`` writes into a topic map).

``--variants`` scores some of them only (``level`` among them or not).

``--scales S ...`` scores instead the level IMU's drives with Y_a multiplied by each S
(an accelerometer's scale error, or a κ taken out wrongly): how precise Y_a must be;
``--self-calibrate`` adds each S's drives with the self-calibrated scale and bias on top;
``--scaled-channel x_v_mps`` puts the scale error on X_v instead (a wheel-speed scale:
tyre wear and pressure); ``--offsets B ...`` puts offsets [m/s²] on the channel instead
(a bias: on Y_a, g·sin of a roll error in the attitude or the mounting).

Every car is scored with its true ``ukf`` file, the models given and the UKF, through a
topic map over the contract topics (scale 1 for ``level`` and ``body``), pooled MAE
[deg] per car. Writes ``OUT`` (JSON), prints a table.

    python training/scripts/validation_benchmark.py --cars 0 1 2 3 4 5 6 7 \
        --out data/val-benchmark-imu-body --imu-frame body    # and 8..15 into -2
    python training/scripts/imu_frame_check.py --level data/val-benchmark \
        --body data/val-benchmark-imu-body \
        --calibration data/val-benchmark-2 data/val-benchmark-2-imu-body \
        --model fleet_ukf_ensemble --out imu-frame-validation.json

``--lever-arm DIR X Y`` scores instead an IMU at (X, Y) m from the CG (``DIR``: the same
drives generated with ``--imu-position X Y``), as recorded and with the topic map's
``imu.position_m`` taking the lever arm out, beside the level IMU at the CG.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import yaml
from scipy.signal import butter, sosfiltfilt

from sideslip_estimator.accelerometer_scale import estimate_scale
from sideslip_msgs_py.bag import read_bag
from sideslip_msgs_py.topic_map import contract_topic_map
from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests, held_out_vehicles
from sideslip_training.accelerometer_check import check_accelerometer
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.init_model import resolve

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED
from held_out_fit import description, pooled_mae, write_true_ukf

SCALED = {"y_a_mps2": "Y_a", "x_v_mps": "X_v"}
"""Channels ``--scales`` can put a scale error on, and their labels."""
CONTRACT_MAP = contract_topic_map()
"""The contract's own topics read through a topic map, so that a variant can scale a
channel or name the IMU's mounting."""


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


def _self_calibrated(runs: list, base: dict, row: dict, key: str) -> dict:
    """The topic map ``base`` with the scale and bias that :func:`estimate_scale`
    measures on ``runs`` (the drives as ``base`` reads them) taken out of its Y_a; the
    estimate is kept in ``row["self_calibration"][key]``."""
    got = estimate_scale(runs, fit_bias=True)
    if got is None:
        raise SystemExit(f"{key}: too little cornering to self-calibrate")
    fix, offset = got.channel_fix
    row.setdefault("self_calibration", {})[key] = {
        "scale": got.scale, "spread": got.spread, "bias_mps2": got.bias_mps2}  # fmt: skip
    spec = json.loads(json.dumps(base))
    y_a = spec["channels"]["y_a_mps2"]
    y_a.update(scale=y_a.get("scale", 1.0) * fix, offset=y_a.get("offset", 0.0) * fix + offset)
    return spec


def _score(
    folder: Path,
    variant: str,
    bags: list[Path],
    spec: dict,
    models: list[str],
    car_files: list[str],
) -> dict[str, float] | int:
    """Pooled MAE per estimator of ``bags`` read through the topic map ``spec``."""
    topic_map = folder / f"{variant.replace(', ', '-').replace(' ', '_')}.yaml"
    topic_map.write_text(yaml.safe_dump(spec, sort_keys=False))
    report = topic_map.with_suffix(".report")
    code = evaluate_main(["--model", *models, "--data", *map(str, bags), "--out", str(report),
                          "--force", "--topic-map", str(topic_map), *car_files])  # fmt: skip
    if code:
        return code
    stems = [Path(m).stem for m in models]
    got = pooled_mae(report, stems, stems[0] if len(stems) == 1 else None)
    return {k: v for k, v in got.items() if "β" not in k}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--level", type=Path, required=True, help="validation_benchmark.py folder")
    p.add_argument("--body", type=Path, help="the same drives, --imu-frame body")
    p.add_argument("--calibration", type=Path, nargs=2, metavar=("LEVEL", "BODY"),
                   help="other cars' drives, level and body, for the typical κ")  # fmt: skip
    p.add_argument("--lever-arm", nargs=3, metavar=("DIR", "X", "Y"),
                   help="score an IMU at (X, Y) m from the CG instead (see module)")  # fmt: skip
    p.add_argument("--model", nargs="+", default=["fleet_ukf_ensemble"])
    p.add_argument("--variants", nargs="+", help="score only these variants")
    p.add_argument("--scales", type=float, nargs="+", help="Y_a scale errors to score (see module)")
    p.add_argument("--offsets", type=float, nargs="+",
                   help="offsets [m/s²] to put on the channel instead (a bias)")  # fmt: skip
    p.add_argument("--scaled-channel", choices=tuple(SCALED), default="y_a_mps2",
                   help="the channel --scales scales (X_v: a wheel-speed scale error)")  # fmt: skip
    p.add_argument("--self-calibrate", action="store_true",
                   help="with --scales: also each scale error self-calibrated")  # fmt: skip
    p.add_argument("--held-out", action="store_true",
                   help="the folders hold the held-out cars' runs (scored once)")  # fmt: skip
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    if (
        args.lever_arm is None
        and args.scales is None
        and args.offsets is None
        and (args.body is None or args.calibration is None)
    ):
        p.error("--body and --calibration are needed without --lever-arm, --scales, --offsets")
    errors = [(f"× {k:g}", k, 0.0) for k in args.scales or ()]
    errors += [(f"{b:+g}", 1.0, b) for b in args.offsets or ()]  # [m/s²]
    fleet = (
        held_out_vehicles()
        if args.held_out
        else {
            v.name: v
            for v in sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
        }
    )
    summary: dict[str, object] = {}
    if errors:
        other = bags_by_car(args.level)
        label = SCALED[args.scaled_channel]
        variants = tuple(f"level, {label} {tag}" for tag, _, _ in errors)
        if args.self_calibrate:
            variants += tuple(f"level, {label} {tag}, self-calibrated" for tag, _, _ in errors)
    elif args.lever_arm is None:
        cal_level, cal_body = (bags_by_car(f) for f in args.calibration)
        typical_cars = {c: gravity_share_true(cal_level[c], cal_body[c]) for c in sorted(cal_level)}
        typical = float(np.median(list(typical_cars.values())))
        print(f"typical κ {typical:.4f} over {len(typical_cars)} calibration cars", file=sys.stderr)
        summary = {"typical_kappa": typical, "calibration_cars": typical_cars}
        other = bags_by_car(args.body)
        variants = ("level", "body", "body, typical scale", "body, own scale",
                    "body, checked scale", "body, self-calibrated")  # fmt: skip
    else:
        other = bags_by_car(Path(args.lever_arm[0]))
        position = [float(args.lever_arm[1]), float(args.lever_arm[2])]
        summary = {"imu_position_m": position}
        variants = ("level", "away", "away, moved to the CG")
    models = [str(resolve(m)) for m in args.model]
    stems = [Path(m).stem for m in models]
    work = args.out.with_suffix(".work")
    level = bags_by_car(args.level)
    results: dict[str, dict[str, object]] = {}
    for car in sorted(other):
        folder = work / car
        folder.mkdir(parents=True, exist_ok=True)
        true_file = write_true_ukf(fleet[car], folder / "true.ukf.yaml", "imu_frame_check.py")
        desc = folder / "description.yaml"
        desc.write_text(yaml.safe_dump(description(fleet[car]), sort_keys=False))
        # Mapped bags record no car: the node's files, the car's true ones.
        car_files = ["--vehicle", str(desc), "--observer-params", str(true_file), "--car",
                     "given", "--ukf-params", str(true_file)]  # fmt: skip
        row: dict[str, object] = {}
        plans: list[tuple[str, list[Path], dict]] = [("level", level[car], CONTRACT_MAP)]
        if errors:
            plans = []
            name, label = args.scaled_channel, SCALED[args.scaled_channel]
            runs = load_runs(level[car])[0] if args.self_calibrate else []
            for tag, k, b in errors:
                spec = json.loads(json.dumps(CONTRACT_MAP))
                spec["channels"][name].update(scale=k, offset=b)
                plans.append((f"level, {label} {tag}", level[car], spec))
                if args.self_calibrate:
                    # The error as the drives would record it, then measured back.
                    scaled = []
                    for r in runs:
                        column = getattr(r.samples, name) * k + b
                        scaled.append(SimpleNamespace(samples=replace(r.samples, **{name: column})))
                    fixed = _self_calibrated(scaled, spec, row, f"{label} {tag}")
                    plans.append((f"level, {label} {tag}, self-calibrated", level[car], fixed))
        elif args.lever_arm is None:
            check = check_accelerometer(load_runs(other[car])[0])
            kappa = {"true": gravity_share_true(level[car], other[car]),
                     "own": gravity_share_own(other[car]),
                     "checked": float("nan") if check is None else check.scale - 1.0}  # fmt: skip
            row["kappa"] = kappa
            scales = {
                "body": 1.0,
                "body, typical scale": 1.0 / (1.0 + typical),
                "body, own scale": 1.0 / (1.0 + kappa["own"]),
                "body, checked scale": 1.0 / (1.0 + kappa["checked"]),
            }
            for variant, scale in scales.items():
                spec = json.loads(json.dumps(CONTRACT_MAP))
                spec["channels"]["y_a_mps2"]["scale"] = scale
                plans.append((variant, other[car], spec))
            if not args.variants or "body, self-calibrated" in args.variants:
                spec = _self_calibrated(load_runs(other[car])[0], CONTRACT_MAP, row, "body")
                plans.append(("body, self-calibrated", other[car], spec))
        else:
            plans.append(("away", other[car], CONTRACT_MAP))
            plans.append(("away, moved to the CG", other[car],
                          {**CONTRACT_MAP, "imu": {"position_m": position}}))  # fmt: skip
        for variant, bags, spec in plans:
            if args.variants and variant not in args.variants:
                continue
            got = _score(folder, variant, bags, spec, models, car_files)
            if isinstance(got, int):
                return got
            row[variant] = got
        results[car] = row
        print(car, json.dumps(row), file=sys.stderr, flush=True)
    summary["cars"] = results
    args.out.write_text(json.dumps(summary, indent=1) + "\n")
    variants = tuple(v for v in variants if not args.variants or v in args.variants)
    for key in [*stems, "UKF"]:
        means = {v: np.mean([r[v][key] for r in results.values()]) for v in variants}  # type: ignore[index]
        print(f"| {key} | " + " | ".join(f"{means[v]:.4f}" for v in variants) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
