"""sideslip-identify-axles: the UKF file from a car's own bags, also another stack's."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from sideslip_estimator.backends.ukf_model import UkfParams
from sideslip_sim.axle_tires import axle_tires
from sideslip_sim.tire import load_tire
from sideslip_sim.ukf_params import ukf_parameters
from sideslip_sim.vehicle import load_vehicle
from sideslip_training.identify_axles import main


@pytest.fixture(scope="module")
def true_file() -> dict:
    car = load_vehicle("compact_rwd")
    return ukf_parameters(car, *axle_tires(car, load_tire(str(car.tire_path()))))


def test_another_stacks_bags_identify_the_cars_cornering_stiffness(
    foreign_bags, true_file, tmp_path, capsys
):
    """From a start 30 % off on both axles, the 100-Hz foreign bags read through the topic
    map give a file the UKF back-end loads, with both axles' B within 5 % of the car's."""
    folder, topic_map = foreign_bags
    start = dict(true_file, mf_b_front=1.3 * true_file["mf_b_front"])
    start["mf_b_rear"] = 0.7 * true_file["mf_b_rear"]
    start_file = tmp_path / "start.ukf.yaml"
    start_file.write_text(yaml.safe_dump(start))
    out = tmp_path / "car.ukf.yaml"
    code = main(["--data", str(folder), "--topic-map", str(topic_map), "--start",
                 str(start_file), "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "wrote" in capsys.readouterr().out
    params = UkfParams.load(str(out))
    assert params.mf_b_front / true_file["mf_b_front"] == pytest.approx(1.0, abs=0.05)
    assert params.mf_b_rear / true_file["mf_b_rear"] == pytest.approx(1.0, abs=0.05)
    assert "identified from 12 recording(s)" in out.read_text()


def test_a_description_is_a_start(foreign_bags, compact_rwd_description, tmp_path, capsys):
    folder, topic_map = foreign_bags
    desc = compact_rwd_description
    out = tmp_path / "my_car.ukf.yaml"
    code = main(["--data", str(folder), "--topic-map", str(topic_map), "--vehicle", str(desc),
                 "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    text = out.read_text()
    assert "starting from the description" in text
    assert UkfParams.load(str(out)).name == "my_car"
    # Identified axles are the car's own: the model's σ for described files is not used.
    assert UkfParams.load(str(out)).axles_from == "recordings"


def test_the_file_made_from_a_description_says_its_axles_are_described(
    compact_rwd_description, tmp_path
):
    from sideslip_training.car_description import Description

    path = tmp_path / "described.ukf.yaml"
    path.write_text(Description.load(compact_rwd_description).ukf_params_yaml())
    assert UkfParams.load(str(path)).axles_from == "description"


def test_an_existing_out_is_not_replaced_without_force(foreign_bags, true_file, tmp_path, capsys):
    folder, topic_map = foreign_bags
    out = tmp_path / "car.ukf.yaml"
    out.write_text("keep me\n")
    start = tmp_path / "start.yaml"
    start.write_text(yaml.safe_dump(true_file))
    code = main(["--data", str(folder), "--topic-map", str(topic_map), "--start", str(start),
                 "--out", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith("sideslip-identify-axles: error: --out") and err.count("\n") == 1
    assert out.read_text() == "keep me\n"


def test_bags_without_a_reference_are_refused(make_arrays, true_file, tmp_path, capsys):
    from sideslip_msgs_py.bag import write_bag
    from sideslip_msgs_py.sample import SensorNoiseSigma

    write_bag(tmp_path / "bags" / "no_truth", make_arrays(2000, truth=False),
              sigma=SensorNoiseSigma.paper(), run_metadata={"name": "no_truth"})  # fmt: skip
    start = tmp_path / "start.yaml"
    start.write_text(yaml.safe_dump(true_file))
    code = main(["--data", str(tmp_path / "bags"), "--start", str(start), "--out",
                 str(tmp_path / "x.yaml")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert "no ground truth" in err
    assert not (tmp_path / "x.yaml").exists()


def test_a_start_that_is_no_ukf_file_is_refused_naming_it(foreign_bags, tmp_path, capsys):
    folder, topic_map = foreign_bags
    start = tmp_path / "start.yaml"
    start.write_text("mass_kg: 1500\n")
    code = main(["--data", str(folder), "--topic-map", str(topic_map), "--start", str(start),
                 "--out", str(tmp_path / "x.yaml")])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 2
    assert "--start:" in err and str(start) in err and err.count("\n") == 1


def test_a_shipped_ukf_file_is_a_start_by_name(foreign_bags, tmp_path, capsys):
    folder, topic_map = foreign_bags
    out = tmp_path / "car.ukf.yaml"
    code = main(["--data", str(folder), "--topic-map", str(topic_map), "--start",
                 "compact_rwd", "--out", str(out)])  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert "starting from the ukf file compact_rwd (shipped)" in out.read_text()


def test_a_nan_splits_a_recording_into_finite_stretches(make_arrays):
    """The zero-phase filter must not run across a gap in a channel or the reference."""
    import dataclasses

    from sideslip_msgs_py.sample import SampleArrays
    from sideslip_training.dataset import Run
    from sideslip_training.identify_axles import recorded_runs

    good = make_arrays(1000)
    cols = {f.name: getattr(good, f.name) for f in dataclasses.fields(good)}
    yaw = cols["yaw_rate_radps"].copy()
    yaw[400:410] = np.nan
    arrays = SampleArrays(**{**cols, "yaw_rate_radps": yaw})
    parts = recorded_runs([Run("r", Path("r"), arrays)])
    assert [p.name for p in parts] == ["r~0", "r~1"]
    assert [p.t_s.size for p in parts] == [400, 590]
    assert all(np.isfinite(p.yaw_rate_radps).all() for p in parts)
