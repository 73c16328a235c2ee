"""The generator CLI: Table 4 bags that stock rosbags readers open, with the contract's
topics at 400 Hz, identical stamps, exact ground truth; and its refusals."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import read_bag
from sideslip_sim.generate_cli import main
from sideslip_sim.vehicle import load_vehicle

CLI = Path(sys.executable).parent / "sideslip-generate"


@pytest.fixture(scope="module")
def paper_test_bags(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("gen") / "paper-test"
    proc = subprocess.run(
        [str(CLI), "--preset", "paper-test", "--out", str(out), "--noise", "paper", "--seed", "4"],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        # A private numba cache makes this process compile the model from scratch, so
        # the in-process regeneration below (cache or fresh) must match it bit for bit.
        env={**os.environ, "PYTHONWARNINGS": "ignore", "NUMBA_CACHE_DIR": str(out.parent / "nb")},
    )
    assert proc.returncode == 0, proc.stderr
    assert "scen1" in proc.stdout and "|β|max°" in proc.stdout
    return out


def test_generate_writes_one_bag_per_run_with_an_index(paper_test_bags):
    bags = sorted(p.name for p in paper_test_bags.iterdir() if p.is_dir())
    assert bags == ["scen1", "scen2", "scen3", "scen4"]
    index = json.loads((paper_test_bags / "index.json").read_text())
    assert [r["name"] for r in index["runs"]] == bags
    assert index["noise"] == "paper" and index["seed"] == 4


def test_bags_open_in_anyreader_with_every_topic_at_400hz_and_identical_stamps(paper_test_bags):
    typestore = get_typestore(Stores.ROS2_JAZZY)
    expected = set(topics.SENSOR_TOPICS) | set(topics.GROUND_TRUTH_TOPICS)
    with AnyReader([paper_test_bags / "scen1"], default_typestore=typestore) as reader:
        assert {c.topic for c in reader.connections} == expected
        stamps: dict[str, list[int]] = {t: [] for t in expected}
        gt_twist, gt_beta = [], []
        for conn, _t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            if conn.topic == topics.GROUND_TRUTH_SIDESLIP:
                gt_beta.append(msg.data)
                continue
            stamp = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            stamps[conn.topic].append(stamp)
            if conn.topic == topics.GROUND_TRUTH_TWIST:
                gt_twist.append((msg.twist.linear.x, msg.twist.linear.y))
    imu = np.array(stamps[topics.IMU])
    assert len(imu) == round(9.5 * 400)
    assert np.all(np.diff(imu) == 2_500_000)  # exactly 400 Hz
    for topic in (topics.TWIST, topics.STEERING, topics.GROUND_TRUTH_TWIST):
        np.testing.assert_array_equal(np.array(stamps[topic]), imu)
    vx, vy = np.array(gt_twist).T
    np.testing.assert_allclose(np.array(gt_beta), np.arctan2(vy, vx), rtol=0, atol=1e-15)


def test_bag_records_its_run_parameters_and_noise_is_on_sensors_only(paper_test_bags):
    contents = read_bag(paper_test_bags / "scen2")
    meta = contents.run_metadata
    assert meta["maneuver"]["scenario"] == "scen2"
    assert meta["vehicle"]["name"] == "paper_sedan"
    assert meta["noise_profile"] == "paper"
    assert meta["tire_file"].endswith(".tir") and len(meta["tire_sha256"]) == 64
    samples = contents.samples
    truth_speed = samples.truth_v_x_mps
    err = samples.x_v_mps - truth_speed
    assert np.std(err) == pytest.approx(1.0 / 3.6, rel=0.1)  # 1 km/h σ
    assert samples.truth_v_y_mps is not None


def test_same_seed_regenerates_identical_samples(paper_test_bags, tmp_path):
    code = main(
        [
            "--preset",
            "paper-test",
            "--out",
            str(tmp_path / "again"),
            "--seed",
            "4",
            "--jobs",
            "1",
            "--quiet",
        ]
    )
    assert code == 0
    first = read_bag(paper_test_bags / "scen4").samples
    second = read_bag(tmp_path / "again" / "scen4").samples
    assert first == second


def test_unknown_preset_is_refused_with_exit_2(tmp_path, capsys):
    assert main(["--preset", "nope", "--out", str(tmp_path / "o")]) == 2
    assert "unknown preset 'nope'" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_non_empty_output_dir_is_refused_without_force(tmp_path, capsys):
    out = tmp_path / "o"
    out.mkdir()
    (out / "keep.txt").write_text("user data")
    assert main(["--preset", "paper-test", "--out", str(out), "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
    assert (
        main(["--preset", "paper-test", "--out", str(out), "--force", "--quiet", "--jobs", "1"])
        == 0
    )
    assert (out / "keep.txt").read_text() == "user data"  # force replaces bags only
    assert (out / "scen1" / "metadata.yaml").is_file()


def test_bad_vehicle_file_is_refused_with_exit_2(tmp_path, capsys):
    bad = tmp_path / "car.yaml"
    bad.write_text("name: car\nmass_kg: 1200\n")
    assert (
        main(["--preset", "paper-test", "--out", str(tmp_path / "o"), "--vehicle", str(bad)]) == 2
    )
    assert "car.yaml" in capsys.readouterr().err


def test_malformed_tyre_file_is_refused_with_exit_2_naming_the_key(tmp_path, capsys):
    sedan = load_vehicle("paper_sedan")
    tire = tmp_path / "tires" / "broken.tir"
    tire.parent.mkdir()
    text = sedan.tire_path().read_text()
    lines = [ln for ln in text.splitlines() if not ln.strip().startswith("PKY1")]
    tire.write_text("\n".join(lines) + "\n")
    car = tmp_path / "vehicles" / "car.yaml"
    car.parent.mkdir()
    shutil.copy(sedan.source_path, car)
    car.write_text(car.read_text().replace(Path(sedan.tire_file).name, "broken.tir"))
    assert (
        main(["--preset", "paper-test", "--out", str(tmp_path / "o"), "--vehicle", str(car)]) == 2
    )
    assert "PKY1" in capsys.readouterr().err


def test_unknown_noise_profile_is_refused_with_exit_2(tmp_path, capsys):
    assert main(["--preset", "paper-test", "--out", str(tmp_path / "o"), "--noise", "x"]) == 2
    assert "noise" in capsys.readouterr().err


def test_second_vehicle_generates_and_differs(tmp_path):
    assert (
        main(
            [
                "--preset",
                "paper-test",
                "--out",
                str(tmp_path / "o"),
                "--vehicle",
                "compact_rwd",
                "--jobs",
                "1",
                "--quiet",
                "--noise",
                "none",
            ]
        )
        == 0
    )
    contents = read_bag(tmp_path / "o" / "scen3")
    assert contents.run_metadata["vehicle"]["name"] == "compact_rwd"
    beta = np.degrees(contents.samples.beta_rad())
    assert math.isfinite(float(np.max(np.abs(beta))))
    assert np.max(np.abs(beta)) > 0.3


def test_a_run_that_loses_control_is_kept_and_flagged_as_spun(tmp_path):
    from sideslip_sim.generate import generate_run
    from sideslip_sim.maneuvers import Maneuver

    car = load_vehicle("compact_rwd")
    # Rear drive, ice, full torque and a hard sine: the car spins, as a real one would.
    severe = Maneuver("ice", "sine_steer", 6.0, 90.0, 900.0, stl_amplitude_m=0.12, mu=0.3)
    gentle = Maneuver("dry", "sine_steer", 6.0, 60.0, 100.0, stl_amplitude_m=0.04)
    spun = generate_run(car, severe, tmp_path, noise="none", seed=0, preset_name="t")
    calm = generate_run(car, gentle, tmp_path, noise="none", seed=0, preset_name="t")
    assert spun.spun and spun.peak_abs_beta_deg > 30.0
    assert not calm.spun
    assert len(read_bag(tmp_path / "ice").samples) == 2400  # kept whole, not dropped
