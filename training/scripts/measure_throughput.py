"""Training throughput (windows per second per epoch) of LSTM/BiLSTM on this machine.

    python training/scripts/measure_throughput.py --data DIR [--device cuda] [--json PATH]

One epoch per configuration on the bags in DIR (stride 1, the paper's sliding window),
after one warm-up epoch; the figures go into bench/results.json (section training).
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
    return {
        "device_name": torch.cuda.get_device_name(0) if torch.cuda.is_available() else "cpu",
        "torch": torch.__version__,
        "threads": torch.get_num_threads(),
        "stride": stride,
        "results": results,
    }


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
