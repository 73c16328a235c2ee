"""Record in a model's file how many of its training bags were recordings
(``provenance["recordings"]``, :mod:`sideslip_msgs_py.data_source`).

``sideslip-train`` and ``sideslip-merge`` record it for every model they write; this
script adds it to a model written before they did, from the bags its command named:
every ``--data``, ``--val`` and ``--rehearse`` folder of the model's command (of each
member's, for a merged model) must be given, and a model fine-tuned from another
(``--init``) is refused, since what its start learnt from is not known here. The bags'
run metadata is read (not their messages); the tensors and the rest of the metadata are
kept, the provenance notes the folders.

    python training/scripts/record_recordings.py MODEL --data data/fleet-train ... --out MODEL
"""

from __future__ import annotations

import argparse
import dataclasses
import shlex
import sys
from pathlib import Path
from typing import Any

from sideslip_msgs_py.artifact import read_artifact, write_artifact
from sideslip_msgs_py.bag import read_run_metadata
from sideslip_msgs_py.data_source import RECORDINGS_KEY, is_simulated
from sideslip_training.bag_paths import find_bags

DATA_OPTIONS = ("--data", "--val", "--rehearse")


def commands(provenance: dict[str, Any]) -> list[str]:
    """The training commands behind a model: its own, or each merged member's."""
    members = provenance.get("merged")
    if members:
        return [str(m.get("command") or "") for m in members]
    return [str(provenance.get("command") or "")]


def named_folders(command: str) -> set[str]:
    """The folders given to ``--data``, ``--val`` and ``--rehearse`` in ``command``;
    raises ValueError for a command that fine-tunes (``--init``) or names none."""
    words = shlex.split(command)
    if "--init" in words:
        raise ValueError(f"fine-tuned from another model ({command!r}): record its start first")
    folders: set[str] = set()
    option = None
    for word in words:
        if word.startswith("--"):
            option = word if word in DATA_OPTIONS else None
        elif option is not None:
            folders.add(word)
    if not folders:
        raise ValueError(f"names no training bags: {command!r}")
    return folders


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("model", type=Path, help="the model file (.safetensors)")
    parser.add_argument(
        "--data", nargs="+", required=True, help="the folders its command(s) named, as named"
    )
    parser.add_argument("--out", type=Path, required=True, help="where to write (may be MODEL)")
    args = parser.parse_args(argv)
    tensors, meta = read_artifact(args.model)
    try:
        named = set().union(*(named_folders(c) for c in commands(meta.provenance)))
    except ValueError as err:
        print(f"{args.model}: {err}", file=sys.stderr)
        return 2
    if missing := sorted(named - set(args.data)):
        print(f"{args.model}: its command named {missing}; give them with --data", file=sys.stderr)
        return 2
    recordings = simulated = 0
    for folder in sorted(named):
        for bag in find_bags([folder]):
            if is_simulated(read_run_metadata(bag)):
                simulated += 1
            else:
                recordings += 1
                print(f"recording: {bag}", file=sys.stderr)
    out = dataclasses.replace(
        meta,
        provenance={
            **meta.provenance,
            RECORDINGS_KEY: recordings,
            "recordings_from": sorted(named),
        },
    )
    write_artifact(args.out, tensors, out, force=True)
    print(f"wrote {args.out}: {recordings} recordings, {simulated} simulated bags")
    return 0


if __name__ == "__main__":
    sys.exit(main())
