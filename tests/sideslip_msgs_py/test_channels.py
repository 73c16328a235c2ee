"""The channel registry: it pins the wire contract, and every channel it names goes
sample -> message -> CDR / bag -> sample unchanged, at the field it names."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py import channels, topics
from sideslip_msgs_py.bag import read_bag, write_bag
from sideslip_msgs_py.cdr import FIELD_COLUMNS, SampleEncoder, decode_columns, layout_field
from sideslip_msgs_py.features import CHANNELS, FEATURE_SET_NAMES
from sideslip_msgs_py.field_path import field_value
from sideslip_msgs_py.messages import (
    FIELDS_RECORDS,
    TypestoreMessages,
    messages_to_sample,
    sample_to_messages,
)
from sideslip_msgs_py.sample import (
    SENSOR_CHANNELS,
    TRUTH_CHANNELS,
    GroundTruth,
    SampleArrays,
    SensorNoiseSigma,
    VehicleSample,
)

FACTORY = TypestoreMessages()
EVERY = (*channels.SENSOR, *channels.TRUTH)

# DESIGN.md's wire contract, written out: a registry edit that moves a channel fails here.
CONTRACT = {
    "x_v_mps": (topics.TWIST, "twist.linear.x"),
    "y_v_mps": (topics.TWIST, "twist.linear.y"),
    "x_a_mps2": (topics.IMU, "linear_acceleration.x"),
    "y_a_mps2": (topics.IMU, "linear_acceleration.y"),
    "yaw_rate_radps": (topics.IMU, "angular_velocity.z"),
    "stl_m": (topics.STEERING, "position[steering_rack]"),
    "stl_rate_mps": (topics.STEERING, "velocity[steering_rack]"),
    "truth_v_x_mps": (topics.GROUND_TRUTH_TWIST, "twist.linear.x"),
    "truth_v_y_mps": (topics.GROUND_TRUTH_TWIST, "twist.linear.y"),
    "truth_yaw_rate_radps": (topics.GROUND_TRUTH_TWIST, "twist.angular.z"),
}


def test_registry_is_the_wire_contract_of_design_md() -> None:
    assert {ch.name: (ch.topic, ch.field) for ch in EVERY} == CONTRACT
    channels.validate()


def test_records_and_tables_derive_from_the_registry_in_its_order() -> None:
    assert SENSOR_CHANNELS == tuple(ch.name for ch in channels.SENSOR)
    assert TRUTH_CHANNELS == tuple(ch.name for ch in channels.TRUTH)
    names = [f.name for f in dataclasses.fields(SampleArrays)]
    assert names == ["stamp_ns", *SENSOR_CHANNELS, *TRUTH_CHANNELS]
    assert [f.name for f in dataclasses.fields(VehicleSample)] == [
        "stamp_ns",
        *SENSOR_CHANNELS,
        "truth",
    ]
    assert [f.name for f in dataclasses.fields(GroundTruth)] == [
        n.removeprefix(channels.TRUTH_PREFIX) for n in TRUTH_CHANNELS
    ]
    assert [f.name for f in dataclasses.fields(SensorNoiseSigma)] == [
        n.name for n in channels.NOISE
    ]
    assert CHANNELS == tuple(ch.name for ch in channels.SENSOR if ch.model_input)
    for topic, record in FIELDS_RECORDS.items():
        assert record._fields == ("stamp_ns", *(ch.name for ch in channels.on_topic(topic)))
    for topic, pairs in FIELD_COLUMNS.items():
        assert pairs == tuple((layout_field(c.field), c.name) for c in channels.on_topic(topic))


def test_feature_sets_named_by_channels_are_known() -> None:
    for ch in channels.SENSOR:
        assert set(ch.feature_sets) <= set(FEATURE_SET_NAMES), ch.name


def test_a_contradicting_registry_is_refused_naming_the_channel(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    bad = dataclasses.replace(channels.SENSOR[0], sigma="no_such_sigma")
    monkeypatch.setattr(channels, "SENSOR", (bad, *channels.SENSOR[1:]))
    with pytest.raises(channels.ChannelRegistryError, match=r"x_v_mps.*no_such_sigma"):
        channels.validate()


def _distinct_samples(n: int = 5) -> SampleArrays:
    """Every channel a different value in every row (so a swapped field shows)."""
    cols = {
        ch.name: 0.125 * (k + 1) + 0.001 * np.arange(n) * (1 if k % 2 else -1)
        for k, ch in enumerate(EVERY)
    }
    return SampleArrays(stamp_ns=10**9 + np.arange(n, dtype=np.int64) * 2_500_000, **cols)


def test_every_channel_sits_at_its_field_and_round_trips_through_messages() -> None:
    samples = _distinct_samples()
    store = FACTORY.typestore
    for i in range(len(samples)):
        sample = samples.row(i)
        msgs = sample_to_messages(sample, FACTORY, SensorNoiseSigma.paper())
        for ch in EVERY:
            expected = getattr(sample, ch.name, None)
            if expected is None:  # a truth channel: on the sample's GroundTruth
                attr = ch.name.removeprefix(channels.TRUTH_PREFIX)
                expected = getattr(sample.truth, attr)
            assert field_value(msgs[ch.topic], ch.field) == expected, ch.name
        raws = {t: store.serialize_cdr(m, m.__msgtype__) for t, m in msgs.items()}
        decoded = {t: store.deserialize_cdr(r, msgs[t].__msgtype__) for t, r in raws.items()}
        assert messages_to_sample(decoded) == sample


def test_every_channel_round_trips_through_the_byte_codec_and_a_bag(tmp_path: Path) -> None:
    samples = _distinct_samples()
    rows = SampleEncoder(SensorNoiseSigma.paper(), FACTORY).encode(samples)
    for topic, pairs in FIELD_COLUMNS.items():
        cols = decode_columns(topic, rows[topic])
        assert cols is not None
        for field, name in pairs:
            np.testing.assert_array_equal(cols[field], getattr(samples, name))
    bag = write_bag(
        tmp_path / "bag", samples, sigma=SensorNoiseSigma.paper(), run_metadata={"run": "x"}
    )
    assert read_bag(bag).samples == samples
