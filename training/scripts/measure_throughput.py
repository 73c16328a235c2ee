"""Training throughput (windows per second per epoch) of LSTM/BiLSTM on this machine.

    python training/scripts/measure_throughput.py --data DIR [--device cuda] [--json PATH]

One epoch per configuration on the bags in DIR (stride 1, the paper's sliding window),
after one warm-up epoch; the figures go into bench/results.json (section training).
Then fine-tuning a merged model of five 64-unit members, member by member against the
wide network trained as one (on every 4th window of that stride: the joined 320-unit
network is slow on a CPU).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch

from sideslip_msgs_py.features import feature_set
from sideslip_training.config import WINDOW_STEPS
from sideslip_training.dataset import load_runs
from sideslip_training.normalize import Normalizer
from sideslip_training.trainer import TrainConfig, train_model
from sideslip_training.windows import WindowIndex


def measure(data: list[str], device: str = "auto", stride: int = 1) -> dict:
    """Windows per second of the second (warm) epoch for four network configurations."""
    features = feature_set("paper")
    runs, _ = load_runs(data)
    norm = Normalizer.fit(runs, features)
    index = WindowIndex.build(runs, features, norm, WINDOW_STEPS, stride)
    val = WindowIndex.build(runs[:1], features, norm, WINDOW_STEPS, 50)
    results = []
    for arch, hidden, batch in [
        ("lstm", 64, 512),
        ("lstm", 64, 2048),
        ("lstm", 128, 512),
        ("bilstm", 64, 512),
    ]:
        cfg = TrainConfig(arch, hidden, 1, 1e-3, 2, 5, batch, 0, device)
        t0 = time.perf_counter()
        result = train_model(cfg, index, val, norm)
        rec = result.history[-1]  # the second epoch: warm
        results.append(
            {
                "architecture": arch,
                "hidden_units": hidden,
                "batch_size": batch,
                "windows": len(index.ends),
                "windows_per_s": rec.windows_per_s,
                "epoch_s": rec.seconds,
                "device": result.device,
                "wall_s_two_epochs": time.perf_counter() - t0,
            }
        )
        print(json.dumps(results[-1]), flush=True)
    merged = merged_fine_tune(runs, features, norm, device, stride * 4)
    return {
        "merged_fine_tune": merged,
        "device_name": torch.cuda.get_device_name(0) if torch.cuda.is_available() else "cpu",
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "stride": stride,
        "results": results,
    }


def merged_fine_tune(runs, features, norm, device: str, stride: int, members: int = 5) -> dict:
    """Fine-tuning a merged model of ``members`` 64-unit LSTMs (random weights, merged as
    ``sideslip-merge`` does): member by member (``keep_members``, the default) against
    the wide network trained as one; windows per second of the second epoch, and the
    ratio measured in this run."""
    from sideslip_msgs_py.artifact import ModelMetadata
    from sideslip_training.merge import merge
    from sideslip_training.model import ModelConfig, SideslipNet

    index = WindowIndex.build(runs, features, norm, WINDOW_STEPS, stride)
    val = WindowIndex.build(runs[:1], features, norm, WINDOW_STEPS, 50)
    nets = []
    for k in range(members):
        torch.manual_seed(k)
        meta = ModelMetadata(
            architecture="lstm", hidden_units=64, layers=1, features=tuple(features),
            window_steps=WINDOW_STEPS, dt_s=0.0025, feature_mean=tuple(norm.mean),
            feature_std=tuple(norm.std), beta_mean=norm.beta_mean, beta_std=norm.beta_std,
            training_data_digest=f"member{k}",
        )  # fmt: skip
        nets.append((SideslipNet(ModelConfig("lstm", len(features), 64, 1)), meta))
    wide, _ = merge(nets, [f"m{k}" for k in range(members)])
    out: dict = {"members": members, "hidden_units": 64 * members, "windows": len(index.ends)}
    for keep in (True, False):
        cfg = TrainConfig(
            hidden_units=64 * members, max_epochs=2, batch_size=512, device=device,
            keep_members=keep,
        )  # fmt: skip
        result = train_model(cfg, index, val, norm, init_state=wide.state_dict(), keep_last=True)
        rec = result.history[-1]
        out["member_by_member" if keep else "joined"] = {
            "windows_per_s": rec.windows_per_s,
            "epoch_s": rec.seconds,
        }
        print(json.dumps({"keep_members": keep, **out}), flush=True)
    out["member_by_member_over_joined"] = (
        out["member_by_member"]["windows_per_s"] / out["joined"]["windows_per_s"]
    )
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", nargs="+", required=True)
    p.add_argument("--device", default="auto")
    p.add_argument("--stride", type=int, default=1)
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (0 = default)")
    p.add_argument("--json", type=Path)
    args = p.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    out = measure(args.data, args.device, args.stride)
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")


if __name__ == "__main__":
    main()
