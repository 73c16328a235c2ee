"""The physics baselines replayed over a run as the node runs them, also over a run cut
in time out of a longer recording."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sideslip_training.dataset import load_runs
from sideslip_training.filter_replay import physics_filter
from sideslip_training.splits import split_in_time


@pytest.mark.parametrize("backend", ["single_track", "ukf"])
def test_a_test_part_is_filtered_as_the_node_ran_through_the_cut(sim_bag_dir: Path, backend):
    """The filter is not started again at the cut: the test part's estimates are those
    of the filter over the whole recording."""
    run = load_runs([sim_bag_dir])[0][0]
    w = 100
    whole = physics_filter(run, backend, "paper_sedan", w)
    _, (tail,) = split_in_time([run], 0.3, "test")
    got = physics_filter(tail, backend, "paper_sedan", w)
    assert len(got) == len(tail.samples) - w + 1
    np.testing.assert_array_equal(got, whole[tail.offset :])
    assert np.isfinite(got).all()
