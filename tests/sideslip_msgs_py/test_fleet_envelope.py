"""The range of a model's training cars: the quantities a car is judged by, the widened
inside test, the union for fine-tuned models and the round trip through the model file."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from sideslip_msgs_py.artifact import ArtifactError, read_artifact, write_artifact
from sideslip_msgs_py.fleet_envelope import (
    MARGIN,
    QUANTITIES,
    EnvelopeError,
    FleetEnvelope,
    quantities_of,
)

from .test_artifact import make_meta, random_tensors

UKF_DIR = Path(__file__).parents[2] / "sideslip_estimator/sideslip_estimator/data/ukf"


def ukf_params(name: str) -> dict:
    return yaml.safe_load((UKF_DIR / f"{name}.yaml").read_text())


def test_quantities_describe_how_the_car_turns():
    p = ukf_params("paper_sedan")
    q = quantities_of(p)
    assert list(q) == list(QUANTITIES)
    wheelbase = p["cg_to_front_axle_m"] + p["cg_to_rear_axle_m"]
    assert q["wheelbase_m"] == pytest.approx(wheelbase)
    # paper_sedan's CG sits 0.72 m behind the front axle: 74 % of the weight on the front.
    assert q["front_weight_fraction"] == pytest.approx(0.7425, abs=1e-4)
    assert q["front_stiffness_per_load"] == pytest.approx(
        p["mf_b_front"] * p["mf_c_front"] * p["mu_peak_front"]
    )


@pytest.mark.parametrize(
    ("key", "value"), [("mass_kg", 0.0), ("mf_b_rear", "x"), ("cg_height_m", None)]
)
def test_a_params_file_with_a_bad_number_is_refused_naming_the_key(key: str, value: object):
    p = {**ukf_params("compact_rwd"), key: value}
    with pytest.raises(EnvelopeError, match=f"car.yaml: {key} must be a number > 0"):
        quantities_of(p, "car.yaml")


def test_a_car_is_inside_its_own_envelope_and_others_are_judged_on_the_widened_range():
    sedan, compact = ukf_params("paper_sedan"), ukf_params("compact_rwd")
    both = FleetEnvelope.of_cars([sedan, compact, sedan])  # duplicates count once
    assert both.cars == 2
    assert both.outside(sedan) == [] and both.outside(compact) == []
    alone = FleetEnvelope.of_cars([compact])
    found = alone.outside(sedan)
    assert any(line.startswith("front_weight_fraction 0.7425 outside") for line in found)
    # Just inside the margin, and just beyond it.
    lo, hi = both.bounds["cg_height_m"]
    pad = MARGIN * (hi - lo)
    inside = {**compact, "cg_height_m": hi + 0.99 * pad}
    beyond = {**compact, "cg_height_m": hi + 1.01 * pad}
    assert both.outside(inside) == []
    assert [line.split(" ")[0] for line in both.outside(beyond)] == ["cg_height_m"]


def test_the_union_covers_both_envelopes():
    sedan, compact = ukf_params("paper_sedan"), ukf_params("compact_rwd")
    union = FleetEnvelope.of_cars([sedan]).union(FleetEnvelope.of_cars([compact]))
    assert union == FleetEnvelope.of_cars([sedan, compact])


@given(
    st.lists(
        st.tuples(st.floats(0.1, 1e4), st.floats(0.0, 1e3)),
        min_size=len(QUANTITIES),
        max_size=len(QUANTITIES),
    ),
    st.integers(1, 10_000),
)
def test_any_envelope_round_trips_through_its_dict(pairs: list, cars: int):
    env = FleetEnvelope(
        {k: (lo, lo + w) for k, (lo, w) in zip(QUANTITIES, pairs, strict=True)}, cars
    )
    assert FleetEnvelope.from_dict(env.to_dict()) == env


@pytest.mark.parametrize(
    ("data", "match"),
    [
        ({"bounds": {}}, "needs exactly the keys"),
        ({"bounds": [], "cars": 1}, "bounds must be an object"),
        ({"bounds": {q: [0, 1] for q in QUANTITIES[1:]}, "cars": 1}, r"missing \['mass_kg'\]"),
        (
            {"bounds": {**{q: [0, 1] for q in QUANTITIES}, "mass_kg": [2, 1]}, "cars": 1},
            "min <= max",
        ),
        (
            {"bounds": {**{q: [0, 1] for q in QUANTITIES}, "mass_kg": [0]}, "cars": 1},
            r"\[min, max\]",
        ),
        ({"bounds": {q: [0, 1] for q in QUANTITIES}, "cars": 0}, "cars must be an integer >= 1"),
    ],
)
def test_a_malformed_envelope_is_refused(data: dict, match: str):
    with pytest.raises(EnvelopeError, match=match):
        FleetEnvelope.from_dict(data)


def test_the_envelope_round_trips_through_the_model_file_and_a_bad_one_is_refused(tmp_path: Path):
    env = FleetEnvelope.of_cars([ukf_params("paper_sedan"), ukf_params("compact_rwd")])
    meta = make_meta(envelope=env.to_dict())
    path = tmp_path / "m.safetensors"
    write_artifact(path, random_tensors(meta), meta)
    _, back = read_artifact(path)
    assert back == meta and FleetEnvelope.from_dict(back.envelope) == env
    with pytest.raises(ArtifactError, match="model metadata: envelope: cars must be"):
        make_meta(envelope={**env.to_dict(), "cars": -1})
