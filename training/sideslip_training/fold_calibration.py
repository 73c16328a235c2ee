"""The errors σ is calibrated on after ``sideslip-train --folds K``: every bag's, each
scored by the fold network that did not train on it (out of fold).

Why: without folds σ is calibrated on the validation split, which for a fine-tune on a
few minutes of a car's driving is about one minute. On the held-out cars the 95 %
intervals calibrated that way covered 82–99 % per car × μ cell (docs/evaluation/
fine-tune-folds): the scale of one minute's errors is not the scale of the car's
other driving. The folds score every bag once, with a network that has not seen it, so
the calibration gets K times the data at no further training.

Each fold's network is scored as the exported model will run: moved toward the start
with ``--interpolate`` as it is (the caller does that).

Only each fold's recorded runs count, not their mirror images: the node averages a
simulated-trained network with its mirror image, and on a mirror image that average's
errors are the recorded run's, mirrored — the same samples twice.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from .calibrate import Errors
from .dataset import Run
from .training_data import MIRROR_SUFFIX


def is_mirror_image(run: Run) -> bool:
    """Whether ``run`` is a mirror image made for training (``<name>~mirror``, or a
    block ``<name>~mirror#k`` of one when the folds split in time)."""
    return run.name.split("#", 1)[0].endswith(MIRROR_SUFFIX)


def out_of_fold_errors(
    folds: Sequence[tuple[Sequence[Run], Any]], meta: Any, car: dict[str, Any]
) -> tuple[list[Run], Errors]:
    """The recorded runs of every fold and their errors, each fold's scored by its own
    model (``folds``: pairs of a fold's runs and the network trained without them);
    ``meta`` and ``car`` as :meth:`.calibrate.Errors.of_runs` takes them. The runs are
    returned in the order of the errors' run indices, as :func:`.calibrate.calibrate`
    takes them with ``errors``.

    Raises:
        ValueError: no fold has a recorded run.
    """
    runs: list[Run] = []
    parts: list[tuple[Errors, int]] = []
    for held, model in folds:
        own = [r for r in held if not is_mirror_image(r)]
        if own:
            parts.append((Errors.of_runs(own, model, meta, **car), len(own)))
            runs.extend(own)
    if not parts:
        raise ValueError("no recorded run in any fold to calibrate on")
    return runs, Errors.concatenate(parts)


__all__ = ["is_mirror_image", "out_of_fold_errors"]
