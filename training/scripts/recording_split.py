"""sideslip-train's defaults against a plain LSTM on recordings split 70/30 in time.

For cars the fleet models never saw (drawn by the fleet sampler with a seed no training
set uses), each car's ~3 minutes of driving (20 fleet-style runs, μ 0.3-1.0) is written
as a 100-Hz "recording" (the 400-Hz simulation resampled, as a real logger would give);
the first 70 % of every run is for training, the last 30 % for the test:

* **defaults**: ``sideslip-train --split time --test-fraction 0.3 --features measurable
  --model lstm`` (quick profile: its own validation part taken from the training 70 %,
  early stopping, the recording's own rate, the 250-ms window, every window of a small
  data set, mirrored runs and averaged weights), scored by its own test step
  (``metrics.json``);
* **plain**: an LSTM of the same size (64 units) on the same measurable channels at the
  recording's 100 Hz, window 25 samples (250 ms), z-scored, Adam 1e-3, MSE, 30 epochs,
  no validation, trained on the same first 70 % and scored on the same last 30 %.

Both with ``--seeds`` seeds (0, 1, ...; weights and shuffling): one training's test RMSE
moved by up to ±40 % between seeds, so the comparison is of the means over seeds.

    python training/scripts/recording_split.py --out data/recording-split

``--init MODEL`` adds a third method on the same recordings, one training per seed:
fine-tuning a shipped or fitted model (``sideslip-train --init MODEL --split time
--test-fraction 0.3``, otherwise the defaults). A model that reads the car or the UKF
(``fleet_ukf_measurable``) gets the car's nominal parameters as a user would give them
(``--vehicle``, ``--observer-params``; here the car's true values, since the recordings,
like a real logger's, carry none). Written to ``results-init-MODEL.json``.

``--offsets`` runs the comparison on copies of the recordings with constant sensor
offsets, as a real car's sensors have them (per car: lateral acceleration ±0.08 m/s²,
yaw rate ±0.15 °/s, steering ±1.5 mm, signs drawn with seed 5), in OUT/recordings-offsets.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from sideslip_msgs_py.bag import read_bag, write_bag
from sideslip_msgs_py.features import FEATURE_SETS
from sideslip_msgs_py.resample import to_step
from sideslip_msgs_py.sample import SensorNoiseSigma
from sideslip_sim.fleet import sample_fleet
from sideslip_sim.generate import generate, prepare_output
from sideslip_sim.held_out import held_out_digests
from sideslip_sim.presets import VehicleRun, fleet_runs
from sideslip_sim.vehicle import vehicle_record
from sideslip_training.cli import train_main
from sideslip_training.dataset import find_bags, load_runs

SEED = 77  # no training set uses it
RUNS_PER_CAR = 20


def make_recordings(out: Path, cars: int) -> list[Path]:
    """Per car a folder of 100-Hz bags (the car's runs); kept when already there."""
    done = sorted((out / "recordings").glob("*")) if (out / "recordings").exists() else []
    if len(done) >= cars:
        return done[:cars]
    fleet = sample_fleet(cars, SEED, prefix="rec", exclude_digests=held_out_digests()).vehicles
    folders = []
    for car in fleet:
        runs = []
        for k in range(RUNS_PER_CAR // 4):
            for r in fleet_runs([car], 4, SEED + k):
                runs.append(
                    VehicleRun(car, dataclasses.replace(r.maneuver, name=f"p{k}_{r.maneuver.name}"))
                )
        sim = out / "sim" / car.name
        prepare_output(sim, force=True)
        generate(runs, sim, seed=SEED, progress=False)
        rec = out / "recordings" / car.name
        prepare_output(rec, force=True)
        loaded, _ = load_runs([sim])
        for run in loaded:
            slow = to_step(run.samples, 0.01).samples  # the logger's 100 Hz
            write_bag(
                rec / run.name,
                slow,
                sigma=SensorNoiseSigma.paper(),
                run_metadata={"name": run.name},
            )
        folders.append(rec)
    return folders


def plain_lstm(
    folder: Path, seed: int = 0, epochs: int = 30, window: int = 25, hidden: int = 64
) -> dict[str, float]:
    """The plain way: first 70 % of each run trains, last 30 % tests, at 100 Hz."""
    torch.manual_seed(seed)
    channels = FEATURE_SETS["measurable"]
    runs, _ = load_runs([folder])
    train_x, train_y, test_x, test_y = [], [], [], []
    for run in runs:
        s = run.samples
        x = np.stack([getattr(s, c) for c in channels], axis=1)
        y = s.beta_rad()
        cut = len(y) - round(0.3 * len(y))
        for (xs, ys), (bx, by) in (
            ((x[:cut], y[:cut]), (train_x, train_y)),
            ((x[cut:], y[cut:]), (test_x, test_y)),
        ):
            if len(ys) < window:
                continue
            w = np.lib.stride_tricks.sliding_window_view(xs, window, axis=0).transpose(0, 2, 1)
            bx.append(w)
            by.append(ys[window - 1 :])
    xtr, ytr = np.concatenate(train_x), np.concatenate(train_y)
    xte, yte = np.concatenate(test_x), np.concatenate(test_y)
    mean, std = xtr.reshape(-1, xtr.shape[-1]).mean(0), xtr.reshape(-1, xtr.shape[-1]).std(0) + 1e-9
    bmean, bstd = ytr.mean(), ytr.std() + 1e-12

    class Net(nn.Module):
        def __init__(self) -> None:
            super().__init__()
            self.lstm = nn.LSTM(len(channels), hidden, batch_first=True)
            self.head = nn.Linear(hidden, 1)

        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return self.head(self.lstm(x)[0][:, -1]).squeeze(-1)

    net = Net()
    opt = torch.optim.Adam(net.parameters(), lr=1e-3)
    xt = torch.tensor((xtr - mean) / std, dtype=torch.float32)
    yt = torch.tensor((ytr - bmean) / bstd, dtype=torch.float32)
    for _ in range(epochs):
        order = torch.randperm(len(yt))
        for i in range(0, len(yt), 256):
            idx = order[i : i + 256]
            opt.zero_grad()
            loss = nn.functional.mse_loss(net(xt[idx]), yt[idx])
            loss.backward()
            opt.step()
    with torch.inference_mode():
        est = net(torch.tensor((xte - mean) / std, dtype=torch.float32)).numpy() * bstd + bmean
    err = np.degrees(est - yte)
    return {
        "mae_deg": float(np.mean(np.abs(err))),
        "rmse_deg": float(np.sqrt(np.mean(err**2))),
        "samples": int(err.size),
    }


OFFSETS = {"y_a_mps2": 0.08, "yaw_rate_radps": math.radians(0.15), "stl_m": 0.0015}


def with_offsets(folders: list[Path], out: Path) -> list[Path]:
    """Copies of the recordings with constant per-car sensor offsets (module docstring)."""
    rng = np.random.default_rng(5)
    copies = []
    for folder in folders:
        signs = rng.choice([-1.0, 1.0], len(OFFSETS))
        dest = out / "recordings-offsets" / folder.name
        for bag in find_bags([folder]):
            s = read_bag(bag).samples  # as recorded (100 Hz), not resampled
            moved = zip(OFFSETS.items(), signs, strict=True)
            shifted = {k: getattr(s, k) + sign * b for (k, b), sign in moved}
            write_bag(
                dest / bag.name,
                dataclasses.replace(s, **shifted),
                sigma=SensorNoiseSigma.paper(),
                run_metadata={"name": bag.name},
                force=True,
            )
        copies.append(dest)
    return copies


def train_and_test(folder: Path, model: Path, seed: int, options: list[str]) -> dict[str, Any]:
    """``sideslip-train`` on ``folder`` split 70/30 in time with ``options``: the model's
    and the smoothed kinematic baseline's test figures, and the wall time [s]."""
    t0 = time.perf_counter()
    args = ["--data", str(folder), "--split", "time", "--test-fraction", "0.3", *options]
    args += ["--seed", str(seed), "--out", str(model), "--force", "--quiet", "--device", "cpu"]
    code = train_main(args)
    if code != 0:
        raise SystemExit(code)
    test = json.loads(model.with_suffix(".run").joinpath("metrics.json").read_text())["test"]
    ours = next(v for k, v in test.items() if k.startswith("LSTM"))
    return {
        "mae_deg": ours["mae_deg"],
        "rmse_deg": ours["rmse_deg"],
        "samples": ours["samples"],
        "seconds": time.perf_counter() - t0,
        "kinematic_20": {k: test["Kinematic (20-step mean)"][k] for k in ("mae_deg", "rmse_deg")},
    }


def defaults(folder: Path, out: Path, seed: int) -> dict[str, Any]:
    """sideslip-train's defaults on ``folder``: its test figures and the baselines'."""
    model = out / "models" / f"{folder.name}_s{seed}.safetensors"
    return train_and_test(folder, model, seed, ["--features", "measurable", "--model", "lstm"])


def car_files(car_name: str, cars: int, out: Path) -> tuple[Path, Path]:
    """The car's description and ``ukf`` params files (its true nominal values)."""
    import yaml

    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_training.physics_params import nominal_parameters

    fleet = sample_fleet(cars, SEED, prefix="rec", exclude_digests=held_out_digests()).vehicles
    car = next(c for c in fleet if c.name == car_name)
    record = vehicle_record(car)
    folder = out / "cars"
    folder.mkdir(parents=True, exist_ok=True)
    description, params = folder / f"{car_name}.yaml", folder / f"{car_name}.ukf.yaml"
    description.write_text(yaml.safe_dump(VehicleDescription.from_mapping(record).to_dict()))
    params.write_text(yaml.safe_dump(nominal_parameters("ukf", record)))
    return description, params


def fine_tuned(
    folder: Path, out: Path, seed: int, init: str, files: tuple[Path, Path]
) -> dict[str, Any]:
    """``sideslip-train --init`` on ``folder`` split in time: its test figures."""
    model = out / "models" / f"{folder.name}_init_{Path(init).stem}_s{seed}.safetensors"
    options = ["--init", init, "--vehicle", str(files[0]), "--observer-params", str(files[1])]
    return train_and_test(folder, model, seed, options)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", type=Path, default=Path("data/recording-split"))
    p.add_argument("--cars", type=int, default=3)
    p.add_argument("--seeds", type=int, default=3, help="trainings per car and method")
    p.add_argument("--offsets", action="store_true", help="on copies with sensor offsets")
    p.add_argument("--init", help="also fine-tune this model (shipped name or file)")
    args = p.parse_args()
    torch.set_num_threads(1)
    results: dict[str, Any] = {}
    folders = make_recordings(args.out, args.cars)
    if args.offsets:
        folders = with_offsets(folders, args.out)
    if args.init:
        for folder in folders:
            files = car_files(folder.name, args.cars, args.out)
            tuned = [fine_tuned(folder, args.out, s, args.init, files) for s in range(args.seeds)]
            results[folder.name] = {
                "fine_tuned": tuned,
                "fine_tuned_mean_rmse_deg": float(np.mean([r["rmse_deg"] for r in tuned])),
            }
            print(folder.name, json.dumps(results[folder.name]), file=sys.stderr)
        name = f"results-init-{Path(args.init).stem}.json"
        (args.out / name).write_text(json.dumps(results, indent=2) + "\n")
        return 0
    for folder in folders:
        ours = [defaults(folder, args.out, seed) for seed in range(args.seeds)]
        plain = []
        for seed in range(args.seeds):
            t1 = time.perf_counter()
            plain.append({**plain_lstm(folder, seed), "seconds": time.perf_counter() - t1})
        results[folder.name] = {
            "defaults": ours,
            "plain": plain,
            "defaults_mean_rmse_deg": float(np.mean([r["rmse_deg"] for r in ours])),
            "plain_mean_rmse_deg": float(np.mean([r["rmse_deg"] for r in plain])),
            "kinematic_20": ours[0]["kinematic_20"],
        }
        print(folder.name, json.dumps(results[folder.name]), file=sys.stderr)
    name = "results-offsets.json" if args.offsets else "results.json"
    (args.out / name).write_text(json.dumps(results, indent=2) + "\n")
    ratio = [r["defaults_mean_rmse_deg"] / r["plain_mean_rmse_deg"] for r in results.values()]
    print(json.dumps({"rmse_defaults_over_plain": ratio, "mean": float(np.mean(ratio))}))
    return 0 if all(math.isfinite(x) for x in ratio) else 1


if __name__ == "__main__":
    sys.exit(main())
