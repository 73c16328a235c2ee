"""The ``ukf`` back-end's cost per ``update`` on one simulated drive, for comparing two
checkouts of the filter (the figures in :mod:`sideslip_estimator.backends.ukf`).

paper_sedan, an 8-s sine steer at 80 km/h to 0.85 of the friction-limited a_y, the
paper's sensor noise (seed 1), the filter's defaults; every sample through ``update`` as
the runtime calls it, three passes, the best one's mean per call. Compare two versions
by running each checkout's copy alternately on an otherwise idle machine, one thread::

    OMP_NUM_THREADS=1 PYTHONPATH=OLD/sideslip_estimator:OLD/sideslip_msgs_py:OLD/sideslip_sim \\
        .venv/bin/python bench/tools/ukf_update_cost.py --label old
    OMP_NUM_THREADS=1 .venv/bin/python bench/tools/ukf_update_cost.py --label new
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from sideslip_estimator.backends import create_backend
from sideslip_estimator.backends.ukf import UkfBackend
from sideslip_msgs_py.features import CHANNELS
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.sensors import add_noise, exact_samples, noise_profile
from sideslip_sim.simulate import simulate
from sideslip_sim.vehicle import load_vehicle


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--label", default="ukf", help="printed before the figures")
    p.add_argument("--passes", type=int, default=3)
    args = p.parse_args()
    drive = Maneuver("sine", "sine_steer", 8.0, 80.0, 300.0, ay_fraction=0.85)
    s = exact_samples(simulate(load_vehicle("paper_sedan"), drive), 10**18)
    s = add_noise(s, noise_profile("paper"), 1)
    rows = np.stack([getattr(s, c) for c in CHANNELS], axis=1)
    defaults = {q.name: q.default for q in UkfBackend.parameters}
    backend = create_backend("ukf", {**defaults, "params_file": "paper_sedan"}, 100)
    per_call = []
    for _ in range(args.passes):
        backend.reset()
        start = time.perf_counter()
        for k in range(len(rows)):
            backend.update(rows[k : k + 1], s.stamp_ns[k : k + 1])
        per_call.append((time.perf_counter() - start) / len(rows) * 1e6)
    print(f"{args.label}: {min(per_call):.1f} µs per update (best of {args.passes} passes:",
          ", ".join(f"{v:.1f}" for v in per_call) + ")")  # fmt: skip


if __name__ == "__main__":
    main()
