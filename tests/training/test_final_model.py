"""What the exported model records of its data, and how a fine-tuning is scored against
its start: the node's default mirror average (``auto``) for each."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from sideslip_training.final_model import deployed_mirror, recordings_learnt


def _plan(start: dict | None, recordings: int | None) -> SimpleNamespace:
    init = None if start is None else SimpleNamespace(meta=SimpleNamespace(provenance=start))
    return SimpleNamespace(init=init, data=SimpleNamespace(recordings=recordings))


@pytest.mark.parametrize(
    ("start", "recordings", "learnt", "kept", "mirror"),
    [
        # A simulated start fine-tuned on a user's recordings: the start is averaged,
        # the fitted network is not; a kept start is the start, averaged as before.
        ({"recordings": 0}, 12, 12, 0, (True, False)),
        # Simulated runs only, start and data: both averaged.
        ({"recordings": 0}, 0, 0, 0, (True, True)),
        # A start fitted to recordings before: neither.
        ({"recordings": 5}, 0, 5, 5, (False, False)),
        # A start whose file does not say (the paper reproductions): neither is averaged.
        ({}, 0, None, None, (False, False)),
        # From scratch: selected on the network alone.
        (None, 0, 0, 0, (False, False)),
    ],
)
def test_a_fine_tuning_records_and_is_scored_by_what_it_and_its_start_learnt_from(
    start, recordings, learnt, kept, mirror
):
    plan = _plan(start, recordings)
    assert recordings_learnt(plan) == learnt
    if start is not None:
        assert recordings_learnt(plan, kept_start=True) == kept
    assert deployed_mirror(plan) == mirror
