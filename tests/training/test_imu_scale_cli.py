"""``sideslip-imu-scale``: from bags without a reference to a topic map whose Y_a is
right, for another stack's bag (its map's own scale kept) and for our own topics; bad
input is one line and exit 2."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_estimator.accelerometer_scale import AccelerometerScale, estimate_scale
from sideslip_msgs_py.topic_map import TopicMap
from sideslip_sim.generate import generate
from sideslip_sim.imu_mounting import ImuMounting
from sideslip_sim.maneuvers import Maneuver
from sideslip_sim.presets import VehicleRun
from sideslip_sim.vehicle import load_vehicle
from sideslip_training.accelerometer_check import check_accelerometer
from sideslip_training.cli_errors import EXIT_BAD_INPUT
from sideslip_training.dataset import load_runs
from sideslip_training.imu_scale_cli import fixed_topic_map, main
from tests.foreign_bag import TOPIC_MAP, Truth, make_truth, write_foreign_bag

SCALE, BIAS = 1.08, 0.15  # what the foreign IMU puts on a_y [-, m/s²]


def _turning(seed: int, rate_hz: float = 100.0) -> Truth:
    """make_truth's slalom with turns laid over it: a slalom at one frequency alone cannot
    tell the scale from the lateral velocity (its heading change is a sinusoid too)."""
    truth = make_truth(round(25 * rate_hz), rate_hz=rate_hz, seed=seed)
    t = (truth.stamp_ns - truth.stamp_ns[0]) * 1e-9
    w = 2 * math.pi * 0.04  # a turn each way every 25 s
    turn = 0.15 * np.sin(w * t + seed)
    beta_turn = 0.01 * np.sin(w * t + seed)  # its lateral velocity: β of 0.6°
    x_v = truth.x_v  # (the noisy one: close enough to the speed the turn is driven at)
    y_a = truth.y_a + x_v * turn + 0.01 * w * np.cos(w * t + seed) * x_v
    return dataclasses.replace(
        truth, r=truth.r + turn, y_v=truth.y_v + beta_turn * x_v, y_a=y_a,
        yaw=truth.yaw + np.cumsum(turn) / rate_hz,
    )  # fmt: skip


@pytest.fixture(scope="module")
def foreign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three 25-s foreign bags (100 Hz) whose accelerometer reads SCALE·a_y + BIAS, in
    half-units: the map's own scale of 2 brings them to m/s²."""
    folder = tmp_path_factory.mktemp("foreign")
    for seed in range(3):
        wrong = dataclasses.replace(truth := _turning(seed), y_a=(truth.y_a * SCALE + BIAS) / 2.0)
        write_foreign_bag(folder / f"drive{seed}", wrong)
    spec = json.loads(json.dumps(TOPIC_MAP))
    spec["channels"]["y_a_mps2"]["scale"] = 2.0
    (folder.parent / "theirs.yaml").write_text(yaml.safe_dump(spec), encoding="utf-8")
    return folder


def test_the_written_map_takes_the_scale_and_bias_out(foreign: Path, tmp_path: Path) -> None:
    out, report = tmp_path / "mine.yaml", tmp_path / "scale.json"
    theirs = foreign.parent / "theirs.yaml"
    code = main(["--data", str(foreign), "--topic-map", str(theirs),
                 "--write-topic-map", str(out), "--json", str(report)])  # fmt: skip
    assert code == 0
    got = json.loads(report.read_text())
    assert got["scale"] == pytest.approx(SCALE, abs=0.01)
    assert got["bias_mps2"] == pytest.approx(BIAS, abs=0.03)
    fixed = yaml.safe_load(out.read_text())
    y_a = fixed["channels"]["y_a_mps2"]
    assert y_a["scale"] == pytest.approx(2.0 / got["scale"], rel=1e-5)  # the map's own 2 kept
    # Through the written map the reference agrees: Y_a is the lateral acceleration.
    runs, _ = load_runs([foreign], topic_map=TopicMap.load(out))
    check = check_accelerometer(runs)
    assert check is not None and check.scale == pytest.approx(1.0, abs=0.01)
    assert abs(check.offset_mps2) < 0.03
    # Everything else of their map is as it was.
    theirs_spec = yaml.safe_load(theirs.read_text())
    del fixed["channels"]["y_a_mps2"], theirs_spec["channels"]["y_a_mps2"]
    assert fixed == theirs_spec


def test_our_own_topics_get_a_map_of_the_contract_topics(tmp_path: Path) -> None:
    car = load_vehicle("compact_rwd")
    drives = (
        Maneuver("sine", "sine_steer", 12.0, 80.0, 0.0, stl_amplitude_m=0.05),
        Maneuver("sweep", "sweep_steer", 12.0, 60.0, 0.0, stl_amplitude_m=0.04, mu=0.7),
        Maneuver("step", "step_steer", 12.0, 60.0, 0.0, stl_amplitude_m=0.03),
    )
    bags = tmp_path / "bags"
    generate([VehicleRun(car, m) for m in drives], bags, progress=False,
             imu=ImuMounting(frame="body"))  # fmt: skip
    out = tmp_path / "map.yaml"
    assert main(["--data", str(bags), "--write-topic-map", str(out)]) == 0
    runs, report = load_runs([bags], topic_map=TopicMap.load(out))
    # The body frame's gravity is gone: the reference check and the estimate agree on 1.
    assert report.accelerometer is not None
    assert report.accelerometer.scale == pytest.approx(1.0, abs=0.01)
    again = estimate_scale(runs, fit_bias=True)
    assert again is not None and again.scale == pytest.approx(1.0, abs=1e-6)


def test_straight_driving_is_refused_naming_the_cornering_it_needs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    car = load_vehicle("compact_rwd")
    generate([VehicleRun(car, Maneuver("s", "straight", 10.0, 80.0, 0.0))], tmp_path / "b",
             progress=False)  # fmt: skip
    assert main(["--data", str(tmp_path / "b")]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("sideslip-imu-scale: error: too little cornering")


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--data", "/nonexistent/bags"], "no such file"),
        (["--topic-map", "{missing}"], "cannot"),
        (["--write-topic-map", "{exists}"], "exists; pass --force"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    foreign: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    args: list[str],
    says: str,
) -> None:
    exists = tmp_path / "exists.yaml"
    exists.write_text("x: 1\n")
    filled = [a.format(missing=tmp_path / "none.yaml", exists=exists) for a in args]
    if "--data" not in filled:
        filled += ["--data", str(foreign)]
    assert main(filled) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("sideslip-imu-scale: error:") and says in err[0]


@settings(max_examples=50, deadline=None)
@given(
    s0=st.floats(0.01, 20.0),
    o0=st.floats(-1.0, 1.0),
    scale=st.floats(0.8, 1.3),
    bias=st.floats(-0.5, 0.5),
    value=st.floats(-20.0, 20.0),
)
def test_the_fix_composes_with_the_maps_own_scale_and_offset(
    s0: float, o0: float, scale: float, bias: float, value: float
) -> None:
    spec = {"channels": {"y_a_mps2": {"topic": "/imu", "field": "a.y", "scale": s0, "offset": o0}}}
    found = AccelerometerScale(scale, 0.001, bias, 5, 1000, 60.0, 0.5)
    fixed = fixed_topic_map(spec, found)["channels"]["y_a_mps2"]
    # The channel as the old map reads it, with the measured scale and bias taken out.
    want = ((value * s0 + o0) - bias) / scale
    assert value * fixed["scale"] + fixed["offset"] == pytest.approx(want, rel=1e-5, abs=1e-5)
    assert spec["channels"]["y_a_mps2"]["scale"] == s0  # the input map is not changed


def test_a_50_hz_imu_with_jittery_stamps_and_a_gap_is_measured(tmp_path: Path) -> None:
    # Stamps 20 ms ± 3 ms apart and a 2-s hole: the runs hold together (split at 0.5 s)
    # and the estimate cuts its own stretches at the hole instead of integrating over it.
    rng = np.random.default_rng(5)
    for seed in range(3):
        truth = _turning(seed, rate_hz=50.0)
        stamps = truth.stamp_ns + rng.integers(-3_000_000, 3_000_000, truth.stamp_ns.size)
        stamps[truth.stamp_ns.size // 2 :] += 2_000_000_000
        wrong = dataclasses.replace(truth, stamp_ns=stamps, y_a=truth.y_a * SCALE + BIAS)
        write_foreign_bag(tmp_path / "bags" / f"drive{seed}", wrong)
    (tmp_path / "theirs.yaml").write_text(yaml.safe_dump(TOPIC_MAP), encoding="utf-8")
    report = tmp_path / "scale.json"
    code = main(["--data", str(tmp_path / "bags"), "--topic-map", str(tmp_path / "theirs.yaml"),
                 "--json", str(report)])  # fmt: skip
    assert code == 0
    got = json.loads(report.read_text())
    assert got["scale"] == pytest.approx(SCALE, abs=0.015)
    assert got["bias_mps2"] == pytest.approx(BIAS, abs=0.04)


def test_no_bias_fits_the_scale_alone_and_the_json_is_valid_without_a_spread(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import sideslip_estimator.accelerometer_scale as accelerometer_scale

    for seed in range(3):  # a scale error alone
        truth = _turning(seed)
        write_foreign_bag(
            tmp_path / "bags" / f"d{seed}", dataclasses.replace(truth, y_a=truth.y_a * SCALE)
        )
    (tmp_path / "theirs.yaml").write_text(yaml.safe_dump(TOPIC_MAP), encoding="utf-8")
    # Fewer chunks than needed for a jackknife: no spread, written as null (valid JSON).
    monkeypatch.setattr(accelerometer_scale, "MIN_CHUNKS", 10)
    report = tmp_path / "scale.json"
    code = main(["--data", str(tmp_path / "bags"), "--topic-map", str(tmp_path / "theirs.yaml"),
                 "--no-bias", "--json", str(report)])  # fmt: skip
    assert code == 0
    text = report.read_text()
    assert "NaN" not in text
    got = json.loads(text)
    assert got["bias_mps2"] == 0.0 and got["scale_spread"] is None and got["chunks"] == 3
    assert got["scale"] == pytest.approx(SCALE, abs=0.01)


def test_a_map_without_the_channels_it_reads_is_refused_naming_them(
    foreign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    spec = json.loads(json.dumps(TOPIC_MAP))
    del spec["channels"]["yaw_rate_radps"]
    bad = tmp_path / "no_yaw_rate.yaml"
    bad.write_text(yaml.safe_dump(spec), encoding="utf-8")
    assert main(["--data", str(foreign), "--topic-map", str(bad)]) == EXIT_BAD_INPUT
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "maps no yaw_rate_radps" in err[0]


def test_an_output_that_cannot_be_written_is_one_line_and_exit_2(
    foreign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "file").write_text("x")
    out = tmp_path / "file" / "map.yaml"  # its folder is a file
    code = main(["--data", str(foreign), "--topic-map", str(foreign.parent / "theirs.yaml"),
                 "--write-topic-map", str(out)])  # fmt: skip
    assert code == EXIT_BAD_INPUT
    assert capsys.readouterr().err.strip().splitlines()[-1].startswith("sideslip-imu-scale: error:")
