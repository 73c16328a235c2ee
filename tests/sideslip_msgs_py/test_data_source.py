"""Whether a model learnt from the simulator only: the run metadata a simulated bag
carries, the model file's count of recordings, and what ``mirror_average`` makes of it."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sideslip_msgs_py.data_source import (
    is_simulated,
    learnt_from_simulation_only,
    mirror_average_on,
    recordings_in,
    total_recordings,
)


@pytest.mark.parametrize(
    ("metadata", "simulated"),
    [
        ({"generator": "sideslip_sim 0.1.0"}, True),
        ({"generator": "sideslip_sim"}, True),
        ({"generator": "sideslip_simulator 2"}, False),  # another tool's name
        ({"generator": "carmaker 12"}, False),
        ({"generator": None}, False),
        ({}, False),  # a car's recording, another stack's bag
    ],
)
def test_only_the_projects_simulator_makes_a_run_simulated(metadata, simulated) -> None:
    assert is_simulated(metadata) is simulated


@pytest.mark.parametrize(
    ("provenance", "count"),
    [({"recordings": 0}, 0), ({"recordings": 3}, 3), ({}, None), ({"recordings": None}, None),
     ({"recordings": True}, None), ({"recordings": -1}, None), ({"recordings": "0"}, None)],
)  # fmt: skip
def test_a_file_that_does_not_say_counts_as_unknown(provenance, count) -> None:
    assert recordings_in(provenance) == count
    assert learnt_from_simulation_only(provenance) is (None if count is None else count == 0)


@given(st.lists(st.one_of(st.none(), st.integers(0, 100)), max_size=6))
def test_recordings_add_up_unless_one_source_is_unknown(counts) -> None:
    total = total_recordings(counts)
    assert total == (None if None in counts else sum(counts))


@pytest.mark.parametrize("setting", ["true", "TRUE", "yes", True])
@pytest.mark.parametrize("provenance", [{}, {"recordings": 0}, {"recordings": 2}])
def test_true_averages_whatever_the_model_learnt_from(setting, provenance) -> None:
    assert mirror_average_on(setting, provenance)


@pytest.mark.parametrize("setting", ["false", "no", False])
@pytest.mark.parametrize("provenance", [{}, {"recordings": 0}, {"recordings": 2}])
def test_false_never_averages(setting, provenance) -> None:
    assert not mirror_average_on(setting, provenance)


def test_auto_averages_only_a_model_that_learnt_from_simulation_alone() -> None:
    assert mirror_average_on("auto", {"recordings": 0})
    assert not mirror_average_on("auto", {"recordings": 1})  # its offsets are kept
    assert not mirror_average_on("auto", {})  # a file that does not say


def test_an_unknown_setting_is_named() -> None:
    with pytest.raises(ValueError, match=r"auto, true, false, got 'sometimes'"):
        mirror_average_on("sometimes", {})
