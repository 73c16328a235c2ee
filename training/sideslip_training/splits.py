"""Which runs train and which validate or test: by bag, or in time within each bag.

No window ever spans the two sides: a bag goes to one side whole, or is cut into
separate runs.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence

from .dataset import DatasetError, Run
from .dataset import cut as cut_run


def bag_rank(seed: int, bag: str) -> str:
    """The rank key of ``bag`` in a seeded split: its place in a sort by this key."""
    # A hash rank, not a shuffled list: deterministic across numpy versions and input
    # order, and adding a bag moves no other bag across the split unless the count changes.
    return hashlib.sha256(f"{seed}\x00{bag}".encode()).hexdigest()


def split_runs(runs: Sequence[Run], val_fraction: float, seed: int) -> tuple[list[Run], list[Run]]:
    """Split runs into (training, validation) by bag: all segments of a bag on one side.

    ``round(val_fraction × bags)`` bags (at least 1, at most bags − 1) go to validation,
    chosen by a seeded hash of the bag name; each side keeps the input order of runs.

    Raises:
        DatasetError: ``val_fraction`` outside [0, 1), no runs, or one bag with
            ``val_fraction`` > 0 (its windows would be on both sides).
    """
    if not 0.0 <= val_fraction < 1.0:
        msg = f"val_fraction must be in [0, 1), got {val_fraction!r}"
        raise DatasetError(msg)
    if not runs:
        raise DatasetError("split_runs: no runs to split")
    if val_fraction == 0.0:
        return list(runs), []
    bags = sorted({r.bag for r in runs})
    if len(bags) < 2:
        msg = (
            f"cannot split 1 bag ({bags[0]}) into training and validation: windows of one "
            "bag on both sides would leak; give more bags or val_fraction=0"
        )
        raise DatasetError(msg)
    n_val = min(max(round(val_fraction * len(bags)), 1), len(bags) - 1)
    val_bags = set(sorted(bags, key=lambda b: bag_rank(seed, b))[:n_val])
    return [r for r in runs if r.bag not in val_bags], [r for r in runs if r.bag in val_bags]


def split_in_time(runs: Sequence[Run], fraction: float, suffix: str) -> tuple[list[Run], list[Run]]:
    """Split each bag in time: its last ``fraction`` of samples (counted over all its
    segments) go to the second list, named ``<name>@<suffix>``, the rest to the first.

    For one long recording, where a split by bag is impossible: no window spans the cut
    (the two sides are separate runs), and nothing depends on bag names. The second side
    remembers its recording (:attr:`~.dataset.Run.recording`): the UKF observer runs
    through the cut, as the node does, rather than starting again there.

    Raises:
        DatasetError: ``fraction`` outside (0, 1), no runs, or a bag so short that a side
            would be empty.
    """
    if not 0.0 < fraction < 1.0:
        raise DatasetError(f"a time split fraction must be in (0, 1), got {fraction!r}")
    if not runs:
        raise DatasetError("split_in_time: no runs to split")
    head: list[Run] = []
    tail: list[Run] = []
    for bag in dict.fromkeys(r.bag for r in runs):
        mine = [r for r in runs if r.bag == bag]
        total = sum(len(r) for r in mine)
        cut = total - round(fraction * total)
        if cut <= 0 or cut >= total:
            msg = f"{bag}: {total} samples are too few to split {fraction:g} off in time"
            raise DatasetError(msg)
        seen = 0
        for r in mine:
            n = len(r)
            if seen + n <= cut:
                head.append(r)
            elif seen >= cut:
                tail.append(dataclasses.replace(r, name=f"{r.name}@{suffix}"))
            else:
                k = cut - seen
                head.append(cut_run(r, 0, k))
                tail.append(cut_run(r, k, n, f"{r.name}@{suffix}"))
            seen += n
    return head, tail
