"""Record the range of a model's training cars in its file (``ModelMetadata.envelope``).

``sideslip-train`` records it for every model that reads the UKF observer; this script
adds it to a model trained before it did, from the same training bags (their recorded
cars, as ``sideslip-train`` takes them): the tensors and the rest of the metadata are
kept, the provenance notes the bags.

    python training/scripts/record_envelope.py MODEL --data data/fleet-train --out MODEL2
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

from sideslip_msgs_py.artifact import read_artifact, write_artifact
from sideslip_training.dataset import load_runs
from sideslip_training.observer import training_envelope


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model", type=Path, help="the model file (.safetensors)")
    parser.add_argument("--data", nargs="+", required=True, help="its training bags")
    parser.add_argument("--out", type=Path, required=True, help="where to write (may be MODEL)")
    args = parser.parse_args(argv)
    tensors, meta = read_artifact(args.model)
    if not meta.needs_observer:
        print(f"{args.model}: reads no UKF observer; nothing to record", file=sys.stderr)
        return 2
    runs, report = load_runs(args.data, step_s=meta.dt_s)
    print(str(report), file=sys.stderr)
    envelope = training_envelope(runs, None)
    out = dataclasses.replace(
        meta,
        envelope=envelope.to_dict(),
        provenance={**meta.provenance, "envelope_from": [str(d) for d in args.data]},
    )
    write_artifact(args.out, tensors, out, force=True)
    for name, (lo, hi) in envelope.bounds.items():
        print(f"{name:28s} {lo:10.4g} .. {hi:10.4g}")
    print(f"wrote {args.out}: {envelope.cars} training cars")
    return 0


if __name__ == "__main__":
    sys.exit(main())
