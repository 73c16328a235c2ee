"""sideslip-train and sideslip-evaluate end to end on small real bags, and their refusals."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_msgs_py.artifact import read_artifact, write_artifact
from sideslip_msgs_py.messages import ImuFields, SteeringFields, TwistFields
from sideslip_msgs_py.sample import SampleArrays
from sideslip_training.cli import train_main
from sideslip_training.dataset import load_runs
from sideslip_training.evaluate import predict_run
from sideslip_training.evaluate_cli import main as evaluate_main
from sideslip_training.export import load_model

TINY = ["--profile", "quick", "--max-epochs", "2", "--device", "cpu", "--quiet"]


def _feed(est: Estimator, s: SampleArrays) -> list[float]:
    """Drive the estimator core with a run's samples as the node would."""
    out = []
    for i in range(len(s)):
        stamp = int(s.stamp_ns[i])
        est.on_twist("twist", TwistFields(stamp, float(s.x_v_mps[i]), float(s.y_v_mps[i])))
        est.on_steering("steering", SteeringFields(stamp, float(s.stl_m[i]), 0.0))
        o = est.on_imu(
            "imu",
            ImuFields(
                stamp, float(s.x_a_mps2[i]), float(s.y_a_mps2[i]), float(s.yaw_rate_radps[i])
            ),
        )
        if o is not None:
            out.append(o.estimate.beta_rad)
    return out


def test_train_export_evaluate_and_run_in_the_estimator(sim_bag_dir: Path, tmp_path: Path):
    model = tmp_path / "lstm.safetensors"
    code = train_main(
        [
            "--data",
            str(sim_bag_dir),
            "--model",
            "lstm",
            "--hidden-units",
            "8",
            "--out",
            str(model),
            *TINY,
        ]
    )
    assert code == 0
    run_dir = tmp_path / "lstm.run"
    for name in ("config.json", "history.json", "metrics.json"):
        assert (run_dir / name).is_file()
    config = json.loads((run_dir / "config.json").read_text())
    assert not set(config["train_bags"]) & set(config["val_bags"]), "split leaks bags"
    _, meta = read_artifact(model)
    assert meta.hidden_units == 8 and meta.architecture == "lstm"
    assert meta.training_data_digest == config["data_digest"]
    assert math.isfinite(meta.metrics["val_mae_deg"])

    report = tmp_path / "report"
    assert (
        evaluate_main(["--model", str(model), "--data", str(sim_bag_dir), "--out", str(report)])
        == 0
    )
    table = (report / "table.md").read_text()
    assert (
        "| LSTM |" in table and "Kinematic (raw)" in table and "Kinematic (20-step mean)" in table
    )
    assert (
        len(list(report.glob("trace_*.png"))) == 4
        and len(list(report.glob("error_pdf_*.png"))) == 4
    )

    # The exported file in the estimator's back-end gives the trainer's network output.
    runs, _ = load_runs([sim_bag_dir])
    net, meta = load_model(model)
    # Its bags are simulated: the node's default averages it with its mirror image.
    expected = predict_run(net, meta, runs[0], mirror_average="auto")
    backend = create_backend("pso_lstm", {"model_file": str(model)}, meta.window_steps)
    assert backend.mirror_average
    est = Estimator(backend, EstimatorParams(window_steps=meta.window_steps, max_gap_s=1.0))
    got = _feed(est, runs[0].samples)
    assert len(got) == len(expected)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-6)


@pytest.fixture(scope="module")
def pso_run(sim_bag_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[list[str], Path]:
    """One quick PSO (36 one-epoch trainings), shared by the tests that resume it: its
    arguments and its model."""
    model = tmp_path_factory.mktemp("pso") / "pso.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--pso", "--out", str(model), *TINY]
    args[args.index("--max-epochs") + 1] = "1"
    args += ["--mirror", "no"]  # 36 trainings: the search is under test, not the data
    assert train_main(args) == 0
    return args, model


def test_pso_run_saves_history_and_resumes_to_the_same_result(pso_run):
    args, model = pso_run
    run_dir = model.with_suffix(".run")
    history = json.loads((run_dir / "pso_history.json").read_text())
    assert len(history["iterations"]) == 6  # quick: 5 iterations after the initial swarm
    assert all(len(it["particles"]) == 6 for it in history["iterations"])
    assert (run_dir / "pso_convergence.png").is_file()
    _, meta = read_artifact(model)
    assert meta.pso is not None and meta.pso["trainings"] == 36
    best = meta.pso["best_val_mae_deg"]
    assert meta.hidden_units == meta.pso["best_hidden_units"]

    # An interrupted PSO continues from its state: here it has nothing left to do.
    assert train_main([*args, "--resume"]) == 0
    _, again = read_artifact(model)
    assert again.pso["best_val_mae_deg"] == best
    assert again.pso["best_hidden_units"] == meta.pso["best_hidden_units"]


def test_refuses_an_existing_output_without_force(sim_bag_dir, tmp_path, capsys):
    out = tmp_path / "m.safetensors"
    out.write_bytes(b"keep me")
    code = train_main(["--data", str(sim_bag_dir), "--model", "lstm", "--out", str(out), *TINY])
    assert code == 2
    assert "exists; pass --force" in capsys.readouterr().err
    assert out.read_bytes() == b"keep me"


def test_refuses_empty_data(tmp_path, capsys):
    empty = tmp_path / "empty"
    empty.mkdir()
    out = tmp_path / "m.safetensors"
    code = train_main(["--data", str(empty), "--model", "lstm", "--out", str(out), *TINY])
    assert code == 2
    err = capsys.readouterr().err
    assert str(empty) in err and err.count("\n") == 1
    assert not out.exists()


def test_refuses_a_feature_the_bags_lack(make_arrays, write_arrays, tmp_path, capsys):
    # A real car's bags without lateral velocity: fine for `measurable`, not for `paper`.
    for i in range(3):
        a = make_arrays(800, seed=i)
        cols = dict(vars(a)) | {"y_v_mps": np.full(len(a), np.nan)}
        write_arrays(f"car{i}", SampleArrays(**cols), folder=tmp_path / "bags")
    out = tmp_path / "m.safetensors"
    base = ["--data", str(tmp_path / "bags"), "--model", "lstm", "--out", str(out), *TINY]
    assert train_main([*base, "--features", "paper"]) == 2
    assert "y_v_mps" in capsys.readouterr().err
    assert train_main([*base, "--features", "measurable", "--hidden-units", "4"]) == 0


def test_evaluate_refuses_a_file_that_is_not_a_model(sim_bag_dir, tmp_path, capsys):
    bad = tmp_path / "x.safetensors"
    bad.write_bytes(b"not a model")
    assert evaluate_main(["--model", str(bad), "--data", str(sim_bag_dir)]) == 2
    assert str(bad) in capsys.readouterr().err


def test_evaluate_takes_a_shipped_model_by_name_and_names_an_unknown_one(
    sim_bag_dir, tmp_path, capsys
):
    assert evaluate_main(["--model", "fleet_lstm_paper", "--data", str(sim_bag_dir)]) == 0
    assert "LSTM [paper_kinematic]" in capsys.readouterr().out
    assert evaluate_main(["--model", "no_such_model", "--data", str(sim_bag_dir)]) == 2
    err = capsys.readouterr().err
    assert "--model no_such_model: no such model file" in err and "fleet_lstm_paper" in err


def test_the_evaluation_report_says_which_row_is_which_model_file(sim_bag_dir, tmp_path):
    """Labels carry a file's stem only where two would collide, so scripts find a
    model's row through metrics.json's model_estimators."""
    from sideslip_training.init_model import resolve

    out = tmp_path / "report"
    names = ["fleet_lstm_paper", "pso_lstm_paper"]
    args = ["--model", *names, "--data", str(sim_bag_dir), "--out", str(out)]
    assert evaluate_main(args) == 0
    summary = json.loads((out / "metrics.json").read_text())
    rows = {r["estimator"] for r in summary["pooled"]}
    labels = summary["model_estimators"]
    assert set(labels) == {str(resolve(n)) for n in names}
    assert set(labels.values()) <= rows and len(set(labels.values())) == 2
    assert evaluate_main(["--model", names[0], names[0], "--data", str(sim_bag_dir)]) == 2


def test_evaluate_leaves_out_non_finite_samples_says_how_many_and_prints_no_nan(
    make_arrays, write_arrays, tmp_path, capsys
):
    bags = tmp_path / "bags"
    for i in range(3):
        write_arrays(f"r{i}", make_arrays(800, seed=i), folder=bags)
    model = tmp_path / "m.safetensors"
    args = ["--data", str(bags), "--model", "lstm", "--hidden-units", "4", "--out", str(model)]
    assert train_main([*args, *TINY]) == 0
    a = make_arrays(600, seed=7)
    cols = dict(vars(a))
    cols["y_v_mps"] = cols["y_v_mps"].copy()
    cols["y_v_mps"][300:305] = np.nan  # a sensor dropout inside the run
    test = tmp_path / "test"
    write_arrays("dropout", SampleArrays(**cols), folder=test)
    capsys.readouterr()
    out = tmp_path / "report"
    assert evaluate_main(["--model", str(model), "--data", str(test), "--out", str(out)]) == 0
    table = capsys.readouterr().out
    assert "nan" not in table.lower()
    assert "Samples left out" in table and "Kinematic (raw): 5" in table
    # The network gives no estimate for the 104 windows that hold a NaN row.
    assert "LSTM: 104" in table
    results = json.loads((out / "metrics.json").read_text())["results"]
    assert all(math.isfinite(r["mae"]) for r in results)
    assert {r["excluded"] for r in results} == {0, 5, 24, 104}  # β = 0 leaves out none


def test_resume_refuses_another_run_s_data(pso_run, make_arrays, write_arrays, tmp_path, capsys):
    args, model = pso_run
    config = (model.with_suffix(".run") / "config.json").read_text()
    other = tmp_path / "other"
    for i in range(3):
        write_arrays(f"o{i}", make_arrays(800, seed=10 + i), folder=other)
    resumed = [*args, "--resume"]
    resumed[resumed.index("--data") + 1] = str(other)
    assert train_main(resumed) == 2
    assert "was started with other data_digest" in capsys.readouterr().err
    assert (model.with_suffix(".run") / "config.json").read_text() == config  # record kept


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--max-epochs", "0"], "max_epochs"),
        (["--hidden-units", "0"], "hidden_units"),
        (["--learning-rate", "-1"], "learning_rate"),
    ],
)
def test_bad_training_settings_are_refused_before_anything_is_written(
    sim_bag_dir, tmp_path, capsys, extra, message
):
    out = tmp_path / "m.safetensors"
    code = train_main(
        ["--data", str(sim_bag_dir), "--model", "lstm", "--out", str(out), *TINY, *extra]
    )
    assert code == 2
    assert message in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "m.run").exists()


def test_bags_shorter_than_a_window_are_refused(make_arrays, write_arrays, tmp_path, capsys):
    for i in range(3):
        write_arrays(f"short{i}", make_arrays(60, seed=i), folder=tmp_path / "bags")
    out = tmp_path / "m.safetensors"
    assert (
        train_main(["--data", str(tmp_path / "bags"), "--model", "lstm", "--out", str(out), *TINY])
        == 2
    )
    assert "no windows" in capsys.readouterr().err
    assert not (tmp_path / "m.run").exists()


def test_bags_at_another_rate_are_resampled_to_the_models_rate_or_refused(
    make_arrays, write_arrays, tmp_path, capsys
):
    for i in range(3):
        write_arrays(f"r400_{i}", make_arrays(800, seed=i), folder=tmp_path / "bags")
    stamps = np.arange(800, dtype=np.int64) * 10_000_000  # 100 Hz
    write_arrays("r100", make_arrays(800, seed=9, stamps_ns=stamps), folder=tmp_path / "bags")
    stamps = np.arange(100, dtype=np.int64) * 50_000_000  # 20 Hz: too slow to resample
    write_arrays("r20", make_arrays(100, seed=8, stamps_ns=stamps), folder=tmp_path / "bags")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "bags"), "--model", "lstm", "--out", str(out), *TINY]
    assert train_main([*args, "--hidden-units", "4"]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert config["sample_period_s"] == pytest.approx(0.0025)
    bags = {b.split("#")[0].removesuffix("~mirror") for b in config["train_bags"]}
    bags |= {b.split("#")[0] for b in config["val_bags"]}
    assert bags == {"r400_0", "r400_1", "r400_2", "r100"}  # r20 refused
    # At a rate of its own the model is trained at that rate.
    out50 = tmp_path / "m50.safetensors"
    args[args.index(str(out))] = str(out50)
    assert train_main([*args, "--hidden-units", "4", "--rate-hz", "100"]) == 0
    assert load_model(out50)[1].dt_s == pytest.approx(0.01)
    assert train_main([*args, "--hidden-units", "4", "--rate-hz", "5000", "--force"]) == 2
    assert "--rate-hz must be within 50-1000 Hz" in capsys.readouterr().err


def test_force_never_replaces_a_folder_that_is_not_a_run_folder(sim_bag_dir, tmp_path, capsys):
    precious = tmp_path / "notes"
    precious.mkdir()
    (precious / "thesis.tex").write_text("keep")
    out = tmp_path / "m.safetensors"
    args = [
        "--data",
        str(sim_bag_dir),
        "--model",
        "lstm",
        "--out",
        str(out),
        "--run-dir",
        str(precious),
    ]
    assert train_main([*args, *TINY, "--force"]) == 2
    assert "not a sideslip-train run folder" in capsys.readouterr().err
    assert (precious / "thesis.tex").read_text() == "keep"


def test_evaluate_resamples_a_bag_at_another_rate_instead_of_scoring_it_wrong(
    sim_bag_dir, tmp_path, capsys
):
    from sideslip_msgs_py.bag import read_bag, write_bag
    from sideslip_msgs_py.sample import SensorNoiseSigma

    model = tmp_path / "m.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "8"]
    assert train_main([*args, "--out", str(model), *TINY]) == 0
    # The same runs as a 200-Hz recording (every other sample) and as a 20-Hz one.
    slow, too_slow = tmp_path / "at200", tmp_path / "at20"
    for i, bag in enumerate(sorted(p for p in sim_bag_dir.iterdir() if p.is_dir())):
        s = read_bag(bag).samples
        for out, every in ((slow, 2), (too_slow, 20)):
            cols = {k: (None if v is None else v[::every]) for k, v in vars(s).items()}
            meta = {"name": f"r{i}"}
            write_bag(
                out / f"r{i}",
                SampleArrays(**cols),
                sigma=SensorNoiseSigma.paper(),
                run_metadata=meta,
            )
    capsys.readouterr()
    assert evaluate_main(["--model", str(model), "--data", str(slow)]) == 0
    captured = capsys.readouterr()
    assert "resampled from 200.0 Hz to 400 Hz" in captured.err
    assert "nan" not in captured.out.lower()
    assert evaluate_main(["--model", str(model), "--data", str(too_slow)]) == 2
    err = capsys.readouterr().err
    assert "20.0 Hz" in err and "400 Hz" in err


def test_bags_of_another_stack_train_and_evaluate_through_a_topic_map(tmp_path, capsys):
    import yaml
    from foreign_bag import TOPIC_MAP, make_truth, write_foreign_bag

    bags = tmp_path / "car"
    for i in range(4):  # other topic names and types, 100 Hz, INS velocity east/north
        write_foreign_bag(bags / f"drive{i}", make_truth(300, seed=i))
    topic_map = tmp_path / "car.yaml"
    topic_map.write_text(yaml.safe_dump(TOPIC_MAP))
    model = tmp_path / "car.safetensors"
    args = ["--data", str(bags), "--topic-map", str(topic_map), "--model", "lstm"]
    assert train_main([*args, "--hidden-units", "4", "--out", str(model), *TINY]) == 0
    # Trained at the bags' own 100 Hz (the car's rate, 25 samples = 250 ms).
    config = json.loads((tmp_path / "car.run" / "config.json").read_text())
    assert config["sample_period_s"] == pytest.approx(0.01)
    assert load_model(model)[1].dt_s == pytest.approx(0.01)
    assert load_model(model)[1].window_steps == 25
    code = evaluate_main(
        ["--model", str(model), "--data", str(bags), "--topic-map", str(topic_map)]
    )
    captured = capsys.readouterr()
    assert code == 0, captured.err
    assert f"read through {topic_map}" in captured.err and "LSTM" in captured.out
    assert "resampled" not in captured.err  # the model runs at the bags' rate
    # Without the map the same bags are not ours: a clear error, exit 2.
    assert evaluate_main(["--model", str(model), "--data", str(bags)]) == 2
    assert "--topic-map" in capsys.readouterr().err


def test_evaluate_without_a_model_scores_the_baselines_and_filters_with_a_pooled_row(
    sim_bag_dir, tmp_path, capsys
):
    out = tmp_path / "report"
    args = ["--data", str(sim_bag_dir), "--out", str(out), "--ukf-params", "paper_sedan"]
    assert evaluate_main([*args, "--single-track-params", "paper_sedan"]) == 0
    table = capsys.readouterr().out
    for row in ("| β = 0 |", "| Kinematic (raw) |", "| Single-track KF |", "| UKF |"):
        assert row in table
    assert "| pooled | UKF |" in table and "| mean | UKF |" in table
    summary = json.loads((out / "metrics.json").read_text())
    pooled = {r["estimator"]: r for r in summary["pooled"]}
    per_bag = [r for r in summary["results"] if r["estimator"] == "β = 0"]
    # Pooled = over all samples: the sample-weighted mean of the per-bag MAEs.
    weighted = sum(r["mae"] * r["n"] for r in per_bag) / sum(r["n"] for r in per_bag)
    assert pooled["β = 0"]["mae"] == pytest.approx(weighted)
    assert pooled["β = 0"]["n"] == sum(r["n"] for r in per_bag)
    # The sim's car is paper_sedan: its own UKF beats answering β = 0.
    assert pooled["UKF"]["mae"] < pooled["β = 0"]["mae"]
    assert evaluate_main(["--data", str(sim_bag_dir), "--ukf-params", "no_such_car"]) == 2
    assert "UKF" in capsys.readouterr().err


def test_one_long_recording_trains_on_its_start_and_is_tested_on_its_end(
    make_arrays, write_arrays, tmp_path, capsys
):
    write_arrays("drive", make_arrays(4000, seed=3), folder=tmp_path / "rec")  # one 10-s bag
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    assert train_main([*args, "--test-fraction", "0.3", "--out", str(out), *TINY]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert config["split"] == "time"
    assert config["train_bags"] == ["drive", "drive~mirror"]  # small data: mirrored too
    assert config["val_bags"] == ["drive@val"] and config["test_bags"] == ["drive@test"]
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    test = metrics["test"]
    assert set(test) == {"LSTM", "β = 0", "Kinematic (raw)", "Kinematic (20-step mean)"}
    # The epoch count chosen on validation, then a refit on training + validation.
    assert metrics["refit_epochs"] == metrics["best_epoch"]
    assert (tmp_path / "m.run" / "refit_history.json").exists()
    # 30 % of 4000 samples, less the first window of the test part.
    assert test["LSTM"]["samples"] == 1200 - 99 and math.isfinite(test["LSTM"]["mae_deg"])


def test_three_bags_with_a_test_part_are_split_by_bag_and_not_refit(
    make_arrays, write_arrays, tmp_path
):
    # auto splits three bags by bag; the test part leaves two for training and
    # validation, which must not turn the recorded split (and --refit auto) into "time".
    for k in range(3):
        write_arrays(f"drive{k}", make_arrays(800, seed=10 + k), folder=tmp_path / "rec")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "rec"), "--model", "lstm", "--hidden-units", "4"]
    assert train_main([*args, "--test-fraction", "0.34", "--out", str(out), *TINY]) == 0
    config = json.loads((tmp_path / "m.run" / "config.json").read_text())
    assert config["split"] == "bag"
    assert len(config["test_bags"]) == 1 and "@" not in config["test_bags"][0]
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert "refit_epochs" not in metrics


def test_the_window_in_seconds_keeps_its_horizon_at_another_rate(
    make_arrays, write_arrays, tmp_path
):
    for i in range(3):
        write_arrays(f"r{i}", make_arrays(800, seed=i), folder=tmp_path / "bags")
    out = tmp_path / "m.safetensors"
    args = ["--data", str(tmp_path / "bags"), "--model", "lstm", "--hidden-units", "4"]
    args += ["--rate-hz", "200", "--window-s", "0.25", "--out", str(out), *TINY]
    assert train_main(args) == 0
    meta = load_model(out)[1]
    assert meta.window_steps == 50 and meta.dt_s == pytest.approx(0.005)


def test_a_model_still_improving_at_its_last_epoch_is_warned_about(sim_bag_dir, tmp_path, capsys):
    out = tmp_path / "m.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "4", *TINY]
    args[args.index("--max-epochs") + 1] = "1"
    assert train_main([*args, "--out", str(out)]) == 0
    err = capsys.readouterr().err  # said even with --quiet
    assert "warning: the best epoch was the last (1 of 1)" in err and "--max-epochs" in err
    metrics = json.loads((tmp_path / "m.run" / "metrics.json").read_text())
    assert metrics["still_improving"] is True


def test_test_bags_shared_with_the_training_data_are_refused(sim_bag_dir, tmp_path, capsys):
    out = tmp_path / "m.safetensors"
    args = ["--data", str(sim_bag_dir), "--test", str(sim_bag_dir / "dlc_70")]
    assert train_main([*args, "--model", "lstm", "--out", str(out), *TINY]) == 2
    assert "--test shares 1 bag(s) with --data" in capsys.readouterr().err


# --- fine-tuning ---------------------------------------------------------------------------


def test_fine_tuning_starts_from_the_models_weights_and_statistics(sim_bag_dir, tmp_path):
    base = tmp_path / "base.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--out", str(base), *TINY]) == 0
    tuned = tmp_path / "tuned.safetensors"
    # A vanishing learning rate: the result must be the starting model itself.
    frozen = ["--data", str(sim_bag_dir), "--init", str(base), "--learning-rate", "1e-12"]
    assert train_main([*frozen, "--out", str(tuned), *TINY]) == 0
    before, after = read_artifact(base), read_artifact(tuned)
    for name, tensor in before[0].items():
        np.testing.assert_allclose(after[0][name], tensor, atol=1e-6, err_msg=name)
    m0, m1 = before[1], after[1]
    assert (m1.architecture, m1.hidden_units, m1.features) == (
        m0.architecture,
        m0.hidden_units,
        m0.features,
    )
    assert m1.feature_mean == m0.feature_mean and m1.beta_std == m0.beta_std  # kept
    assert m1.provenance["init"] == "base.safetensors"
    assert m1.provenance["normalization"] == "keep"
    # Simulated bags only, the start's as well: the node's mirror_average auto is on.
    assert m0.provenance["recordings"] == m1.provenance["recordings"] == 0
    refit = tmp_path / "refit.safetensors"
    assert train_main([*frozen, "--normalization", "refit", "--out", str(refit), *TINY]) == 0
    assert read_artifact(refit)[1].provenance["normalization"] == "refit"


def test_a_fine_tuning_that_never_beats_its_start_keeps_the_start_and_says_so(
    sim_bag_dir, tmp_path, capsys
):
    base = tmp_path / "base.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--out", str(base), *TINY]) == 0
    ruined = tmp_path / "ruined.safetensors"
    # Steps too small to change the validation MAE: no epoch is better than the start,
    # so the start's weights come back exactly (the trainer's own test makes it worse).
    wild = ["--data", str(sim_bag_dir), "--init", str(base), "--learning-rate", "1e-12"]
    capsys.readouterr()
    assert train_main([*wild, "--out", str(ruined), *TINY]) == 0
    assert "no epoch of fine-tuning beat the starting model" in capsys.readouterr().err
    before, after = read_artifact(base), read_artifact(ruined)
    for name, tensor in before[0].items():
        np.testing.assert_array_equal(after[0][name], tensor, err_msg=name)
    metrics = json.loads((tmp_path / "ruined.run" / "metrics.json").read_text())
    assert metrics["kept_start_weights"] is True and metrics["best_epoch"] == 0


def test_interpolate_exports_the_weights_that_share_of_the_way_from_the_start(
    sim_bag_dir, tmp_path
):
    base = tmp_path / "base.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--out", str(base), *TINY]) == 0
    # A start whose file does not say what it learnt from (as the paper reproductions):
    # start and epochs are scored alone. (On these four 1-s bags two epochs do not beat
    # a start that learnt from simulated runs both alone and averaged, the bar then.)
    tensors, meta = read_artifact(base)
    provenance = {k: v for k, v in meta.provenance.items() if k != "recordings"}
    write_artifact(base, tensors, dataclasses.replace(meta, provenance=provenance), force=True)
    tune = ["--data", str(sim_bag_dir), "--init", str(base), *TINY]
    full, half = tmp_path / "full.safetensors", tmp_path / "half.safetensors"
    assert train_main([*tune, "--out", str(full)]) == 0
    assert json.loads((tmp_path / "full.run" / "metrics.json").read_text())["best_epoch"] > 0
    assert train_main([*tune, "--interpolate", "0.5", "--out", str(half)]) == 0
    start, tuned, mixed = (read_artifact(p)[0] for p in (base, full, half))
    for name, t0 in start.items():
        expected = t0 + np.float32(0.5) * (tuned[name] - t0)
        np.testing.assert_allclose(mixed[name], expected, atol=1e-6, err_msg=name)
        assert not np.allclose(tuned[name], t0), name  # the fine-tuning moved every tensor
    metrics = json.loads((tmp_path / "half.run" / "metrics.json").read_text())
    assert metrics["interpolate"] == 0.5
    assert metrics["fine_tuned_val_mae_deg"] > 0 and metrics["val_mae_deg"] > 0


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--model", "lstm"], "there is no --init"),
        (["--normalization", "refit"], "needs --normalization keep"),
        (["--interpolate", "0"], "--interpolate must be within (0, 1], got 0.0"),
    ],
)
def test_interpolate_without_a_comparable_start_is_refused_in_one_line(
    sim_bag_dir, tmp_path, capsys, extra, named
):
    base = tmp_path / "base.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--out", str(base), *TINY]) == 0
    capsys.readouterr()
    out = tmp_path / "t.safetensors"
    init = [] if extra[0] == "--model" else ["--init", str(base)]
    alpha = [] if "--interpolate" in extra else ["--interpolate", "0.5"]
    argv = ["--data", str(sim_bag_dir), *init, *alpha, *extra, "--out", str(out), *TINY]
    assert train_main(argv) == 2
    err = capsys.readouterr().err
    assert named in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("extra", "named"),
    [
        (["--features", "measurable"], "--features measurable (the model reads paper)"),
        (["--window-steps", "50"], "a window of 50 steps (the model's is 100)"),
        (["--rate-hz", "200"], "--rate-hz 200 (the model runs at 400 Hz)"),
        (["--hidden-units", "9"], "--hidden-units 9 (the model has 6)"),
        (["--model", "bilstm"], "--model bilstm (the model is lstm)"),
        (["--pso"], "--pso searches the hidden units"),
    ],
)
def test_init_refuses_a_model_that_does_not_fit_in_one_line(
    sim_bag_dir, tmp_path, capsys, extra, named
):
    base = tmp_path / "base.safetensors"
    args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "6"]
    assert train_main([*args, "--out", str(base), *TINY]) == 0
    capsys.readouterr()
    out = tmp_path / "t.safetensors"
    assert (
        train_main(
            ["--data", str(sim_bag_dir), "--init", str(base), *extra, "--out", str(out), *TINY]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert named in err and "does not fit" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_init_takes_a_shipped_model_by_name_and_refuses_an_unknown_one(
    sim_bag_dir, tmp_path, capsys
):
    out = tmp_path / "t.safetensors"
    args = ["--data", str(sim_bag_dir), "--out", str(out), *TINY]
    args[args.index("--max-epochs") + 1] = "1"
    assert train_main(["--init", "fleet_lstm_paper", *args]) == 0
    meta = read_artifact(out)[1]
    assert meta.provenance["init"] == "fleet_lstm_paper.safetensors"
    assert meta.prior == "kinematic_window"
    assert train_main(["--init", "no_such_model", *args, "--force"]) == 2
    assert "shipped: " in capsys.readouterr().err


def test_the_run_metrics_are_strict_json_with_null_for_an_undefined_figure(
    sim_bag_dir: Path, tmp_path: Path
) -> None:
    """A straight test run has a constant β, so its R² is undefined: metrics.json says
    null (any JSON reader opens it), never NaN."""
    out = tmp_path / "m.safetensors"
    train = [str(sim_bag_dir / n) for n in ("dlc_70", "sine_60", "sine_80")]
    args = ["--data", *train, "--test", str(sim_bag_dir / "straight_50"), "--model", "lstm"]
    assert train_main([*args, "--hidden-units", "4", "--out", str(out), *TINY]) == 0

    def refuse(name: str) -> None:
        raise AssertionError(f"metrics.json holds {name}")

    text = (tmp_path / "m.run" / "metrics.json").read_text()
    metrics = json.loads(text, parse_constant=refuse)
    assert any(v["r2"] is None for v in metrics["test"].values())
