"""The node's own Y_a check (``imu_scale.mode``) on validation cars' drives, as a car
would meet it: drive after drive, the node restarted for each and its measurement kept
in ``imu_scale.state_file`` between them.

For every car of ``--level`` / ``--body`` (the same drives generated with
``validation_benchmark.py --imu-frame level`` and ``body``) and every back-end
(``--backends``: ``ukf`` with the car's true file, and ``pso_lstm:NAME`` for a shipped
model read with the same file), the drives are replayed through the estimator core in
``--orders`` shuffled orders (seeded) with

- ``off``: Y_a as recorded;
- ``apply``: the check measuring from the first drive on, correcting once confident;
- ``apply, warm``: the state a previous pass over all the car's drives left (a car that
  has driven before).

Pooled MAE [deg] of β̂ over all samples with an estimate, per car, mode and back-end,
and the driving [s] before the correction began; written to ``--out`` (JSON), printed.

    python training/scripts/online_imu_scale_check.py --level data/val-benchmark \
        --body data/val-benchmark-imu-body --cars 0 1 2 3 4 5 6 7 --out online.json

``--held-out NAME ...`` scores held-out cars instead (``--level`` / ``--body``: the
``sideslip-generate --preset held-out`` runs, ``--imu-frame level`` and ``body``).
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.imu_scale import ImuScale, ImuScaleParams
from sideslip_estimator.replay import replay, replay_columns
from sideslip_msgs_py.bag import read_bag
from sideslip_sim.fleet import sample_fleet
from sideslip_sim.held_out import held_out_digests, held_out_vehicles

sys.path.insert(0, str(Path(__file__).parent))
from fit_bags_check import VAL_CARS, VAL_SEED
from held_out_fit import description, write_true_ukf

WINDOW = 100


def _backend(name: str, ukf_file: Path):
    if name == "ukf":
        return create_backend("ukf", {"params_file": str(ukf_file)}, WINDOW)
    model = name.split(":", 1)[1]
    files = {"observer_params_file": str(ukf_file), "vehicle_file": str(_description(ukf_file))}
    return create_backend("pso_lstm", {"model_file": model, **files}, WINDOW)


def _description(ukf_file: Path) -> Path:
    """The car's description, written beside its ukf file (what a model's
    ``vehicle_file`` reads)."""
    return ukf_file.with_suffix(".description.yaml")


def _drive(
    samples, backend_name: str, ukf_file: Path, imu_scale: ImuScale | None
) -> tuple[np.ndarray, np.ndarray, float]:
    """|β̂ − β| [deg] per sample (NaN where none), whether Y_a was corrected there, and
    the drive's duration [s]."""
    applied = []
    est = Estimator(_backend(backend_name, ukf_file), EstimatorParams(WINDOW), imu_scale)
    if imu_scale is not None:
        feed = imu_scale.feed

        def spy(row, stamp_ns):
            feed(row, stamp_ns)
            applied.append(imu_scale.applied is not None)

        imu_scale.feed = spy  # type: ignore[method-assign]
    got = replay(est, replay_columns(samples))
    if imu_scale is not None:
        imu_scale.feed = feed  # type: ignore[method-assign]
        imu_scale.save(final=True)  # the node's shutdown
    err = np.degrees(np.abs(got.beta_rad - samples.beta_rad()))
    duration = (samples.stamp_ns[-1] - samples.stamp_ns[0]) * 1e-9
    return err, np.asarray(applied or [False] * len(err)), float(duration)


def _chain(drives, backend, ukf_file, params) -> dict[str, float]:
    """Replay ``drives`` in order, one ImuScale across them (``params``: None = off)."""
    scale = None if params is None else ImuScale(params, EstimatorParams().max_gap_s)
    if scale is not None:
        scale.load()
    errors, before_s, started = [], 0.0, False
    for samples in drives:
        err, applied, duration = _drive(samples, backend, ukf_file, scale)
        errors.append(err)
        if not started and applied.any():
            started = True
            before_s += duration * float(np.argmax(applied)) / len(applied)
        elif not started:
            before_s += duration
    err = np.concatenate(errors)
    out = {"mae_deg": float(np.nanmean(err)), "samples": int(np.isfinite(err).sum())}
    if scale is not None:
        out["driving_before_applied_s"] = before_s if started else None
        est = scale.online.estimate
        out["scale"] = None if est is None else est.scale
        out["bias_mps2"] = None if est is None else est.bias_mps2
        out["remounts"] = scale.online.remounts
    return out


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--level", type=Path, required=True)
    p.add_argument("--body", type=Path, required=True)
    p.add_argument("--cars", type=int, nargs="+", help="validation car indices")
    p.add_argument("--held-out", nargs="+", metavar="NAME",
                   help="held-out cars by name instead (their runs: scored once)")  # fmt: skip
    p.add_argument("--backends", nargs="+", default=["ukf"])
    p.add_argument("--orders", type=int, default=3)
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args(argv)
    if bool(args.cars) == bool(args.held_out):
        p.error("give --cars or --held-out")
    if args.held_out:
        cars = [held_out_vehicles()[name] for name in args.held_out]
    else:
        fleet = sample_fleet(VAL_CARS, VAL_SEED, exclude_digests=held_out_digests()).vehicles
        cars = [fleet[k] for k in args.cars]
    results: dict = {}
    tmp = Path(tempfile.mkdtemp(prefix="online-imu-scale-"))
    for car in cars:
        ukf_file = write_true_ukf(car, tmp / f"{car.name}.yaml", "online_imu_scale_check.py")
        _description(ukf_file).write_text(yaml.safe_dump(description(car), sort_keys=False))
        for frame, folder in (("level", args.level), ("body", args.body)):
            bags = sorted(b for b in folder.iterdir() if b.name.startswith(f"{car.name}_"))
            drives = [read_bag(b).samples for b in bags]
            for backend in args.backends:
                row = results.setdefault(car.name, {}).setdefault(frame, {})
                row.setdefault(backend, {})["off"] = _chain(drives, backend, ukf_file, None)
                warm_file = tmp / f"{car.name}-{frame}-warm.json"
                # The warm state: one pass over all drives, measuring only.
                warm = ImuScale(ImuScaleParams("report", str(warm_file)), 0.1)
                for samples in drives:
                    for i, s in enumerate(samples.stamp_ns.tolist()):
                        warm.online.add(
                            s,
                            float(samples.x_v_mps[i]),
                            float(samples.yaw_rate_radps[i]),
                            float(samples.y_a_mps2[i]),
                        )
                    warm.online.end_stretch()
                warm.save()
                for order in range(args.orders):
                    shuffled = list(drives)
                    random.Random(order).shuffle(shuffled)
                    state = tmp / f"{car.name}-{frame}-{order}.json"
                    state.unlink(missing_ok=True)
                    cold = _chain(shuffled, backend, ukf_file, ImuScaleParams("apply", str(state)))
                    row[backend].setdefault("apply", []).append(cold)
                    warm_copy = tmp / f"{car.name}-{frame}-{order}-warm.json"
                    warm_copy.write_text(warm_file.read_text())
                    hot = _chain(
                        shuffled, backend, ukf_file, ImuScaleParams("apply", str(warm_copy))
                    )
                    row[backend].setdefault("apply, warm", []).append(hot)
                print(car.name, frame, backend, json.dumps(row[backend]), flush=True)
        args.out.write_text(json.dumps(results, indent=1))
    _table(results, args.backends)
    return 0


def _table(results: dict, backends: list[str]) -> None:
    for backend in backends:
        print(f"\n{backend}: pooled MAE [deg], mean over orders; driving before applied [s]")
        print("car | level: off, apply, warm | body: off, apply, warm | before applied [s]")
        for car, row in results.items():
            cells = []
            for frame in ("level", "body"):
                r = row[frame][backend]
                cells += [
                    f"{r['off']['mae_deg']:.4f}",
                    f"{np.mean([x['mae_deg'] for x in r['apply']]):.4f}",
                    f"{np.mean([x['mae_deg'] for x in r['apply, warm']]):.4f}",
                ]
            before = [x["driving_before_applied_s"] for x in row["body"][backend]["apply"]]
            cells.append(", ".join("never" if b is None else f"{b:.0f}" for b in before))
            print(car, "|", " | ".join(cells))


if __name__ == "__main__":
    sys.exit(main())
