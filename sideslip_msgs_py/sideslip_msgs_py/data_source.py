"""Whether a model learnt from the project's simulator only, or also from recordings.

A run written by ``sideslip-generate`` names its generator (``sideslip_sim <version>``)
in the bag's run metadata; anything else (a car's recording, a bag of another stack, a
``sideslip-record`` of live topics) counts as a recording. The difference matters at
deployment: the simulator is exactly symmetric left-right, so a network that learnt
from it alone may be averaged with its own mirror image (``pso_lstm.mirror_average``),
while a network fitted to a real car's recordings may have learnt its sensors' offsets
and the car's own asymmetry, which the mirror average would cancel.

The model file records the count under ``provenance["recordings"]``: the training and
validation bags that are recordings, plus those of the model it was fine-tuned from and
of a merged model's members. A file without the key (written before it existed, or
started from such a file) says nothing either way.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any, Final

SIMULATOR: Final = "sideslip_sim"
"""The ``generator`` of every simulated run's metadata starts with this name."""

RECORDINGS_KEY: Final = "recordings"
"""The model provenance key: how many of its (and its start's) bags were recordings."""


def is_simulated(run_metadata: Mapping[str, Any]) -> bool:
    """Whether a bag's run metadata says the project's simulator wrote it."""
    generator = run_metadata.get("generator")
    return isinstance(generator, str) and generator.split(" ", 1)[0] == SIMULATOR


def recordings_in(provenance: Mapping[str, Any]) -> int | None:
    """The recordings a model learnt from (``provenance["recordings"]``), or None when
    its file does not say."""
    value = provenance.get(RECORDINGS_KEY)
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        return None
    return value


def total_recordings(counts: Iterable[int | None]) -> int | None:
    """The sum of several sources' recordings; None when any of them is unknown."""
    total = 0
    for count in counts:
        if count is None:
            return None
        total += count
    return total


def learnt_from_simulation_only(provenance: Mapping[str, Any]) -> bool | None:
    """True when the model records that it learnt from simulated runs only, False when
    it learnt from at least one recording, None when its file does not say."""
    count = recordings_in(provenance)
    return None if count is None else count == 0


MIRROR_AVERAGE_SETTINGS: Final = ("auto", "true", "false")
"""``pso_lstm.mirror_average`` (``sideslip-evaluate --mirror-average`` says yes / no)."""


def mirror_average_on(setting: str | bool, provenance: Mapping[str, Any]) -> bool:
    """Whether to average a network with its mirror image: ``true`` / ``yes`` and
    ``false`` / ``no`` as given; ``auto`` when the model learnt from simulated runs only
    (:func:`learnt_from_simulation_only`), so that offsets a model learnt from a real
    car's recordings are kept. Raises ValueError naming an unknown setting."""
    if isinstance(setting, bool):
        return setting
    word = setting.strip().lower()
    if word in ("true", "yes"):
        return True
    if word in ("false", "no"):
        return False
    if word == "auto":
        return learnt_from_simulation_only(provenance) is True
    raise ValueError(f"must be one of {', '.join(MIRROR_AVERAGE_SETTINGS)}, got {setting!r}")
