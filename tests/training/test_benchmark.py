"""sideslip-benchmark on a few short held-out runs: what it writes, and what it refuses."""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py.bag import read_bag
from sideslip_training import benchmark_data, benchmark_estimators
from sideslip_training.benchmark import main
from sideslip_training.benchmark_estimators import (
    KINEMATIC_MEAN,
    KINEMATIC_RAW,
    SINGLE_TRACK,
    UKF,
    ZERO,
)
from sideslip_training.cli import train_main

TINY = ["--profile", "quick", "--max-epochs", "1", "--device", "cpu", "--quiet"]
SHORT_S = 1.5  # runs cut to 600 samples: five full windows and more, a second to score


def _short_held_out_runs(picks: list[tuple[str, float, str]]) -> list:
    """Preset runs (car, μ, run kind) cut to SHORT_S seconds; the cars stay held-out cars."""
    chosen = []
    for r in benchmark_data.held_out_runs():
        m = r.maneuver
        kind = m.scenario or m.family
        if (r.vehicle.name, m.mu, kind) in picks:
            chosen.append(
                dataclasses.replace(r, maneuver=dataclasses.replace(m, duration_s=SHORT_S))
            )
    assert len(chosen) == len(picks)
    return chosen


PICKS = [
    ("heldout_hatchback_fwd", 1.0, "scen2"),
    ("heldout_hatchback_fwd", 1.0, "sweep_steer"),
    ("heldout_hatchback_fwd", 0.4, "scen2"),
    ("heldout_sedan_rwd", 0.7, "step_steer"),
]


@pytest.fixture(scope="session")
def held_out_bags(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Four short held-out runs on two cars and three μ, as sideslip-generate writes them."""
    from sideslip_sim.generate import generate

    out = tmp_path_factory.mktemp("held_out")
    generate(_short_held_out_runs(PICKS), out, preset_name="held-out", progress=False)
    return out


@pytest.fixture(scope="session")
def tiny_models(sim_bag_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Two tiny trained models: `paper` features (with Y_v) and `measurable` (without)."""
    folder = tmp_path_factory.mktemp("models")
    models = {}
    for features in ("paper", "measurable"):
        path = folder / f"tiny_{features}.safetensors"
        args = ["--data", str(sim_bag_dir), "--model", "lstm", "--hidden-units", "4"]
        assert train_main([*args, "--features", features, "--out", str(path), *TINY]) == 0
        models[features] = path
    return models


@pytest.fixture(scope="module")
def report(held_out_bags: Path, tiny_models: dict[str, Path], tmp_path_factory) -> Path:
    """One benchmark over the four runs: shipped models plus the two tiny ones."""
    out = tmp_path_factory.mktemp("report") / "held-out"
    code = main(
        [
            "--data", str(held_out_bags), "--out", str(out), "--jobs", "2", "--quiet",
            "--model", f"tiny paper={tiny_models['paper']}",
            "--model", f"tiny measurable={tiny_models['measurable']}",
        ]
    )  # fmt: skip
    assert code == 0
    return out


def _results(out: Path) -> dict:
    return json.loads((out / "results.json").read_text())


def test_writes_results_readme_figures_and_car_files_for_every_estimator(report: Path):
    from sideslip_sim.held_out import is_held_out
    from sideslip_sim.vehicle import load_vehicle

    res = _results(report)
    shipped = [n["label"] for n in res["networks"][:-2]]
    assert len(shipped) == len(benchmark_estimators.shipped_model_paths()) >= 1
    assert res["estimators"] == [
        ZERO, KINEMATIC_RAW, KINEMATIC_MEAN, SINGLE_TRACK, UKF, *shipped,
        "tiny paper", "tiny measurable",
    ]  # fmt: skip
    assert [(r["vehicle"], r["mu"], r["kind"]) for r in res["runs"]] == PICKS
    for run in res["runs"]:
        for name, m in run["estimators"].items():
            for key in ("mae_deg", "me_deg", "rmse_deg", "r2", "max_abs_deg"):
                assert m[key] is not None and math.isfinite(m[key]), (run["run"], name, key)
    assert len(res["cells"]) == 3 and len(res["vehicles"]) == 2
    assert set(res["overall_mean_over_cells"]) == set(res["estimators"])
    assert res["machine"]["cpu_count"] >= 1 and res["command"].startswith("sideslip-benchmark ")

    cars = ("heldout_hatchback_fwd", "heldout_sedan_rwd")
    figures = {p.name for p in (report / "figures").iterdir()}
    assert figures == {"mae_by_cell.png", "mae_per_run.png", *(f"trace_{c}.png" for c in cars)}
    for car in cars:
        vehicle = load_vehicle(report / "vehicles" / f"{car}.yaml")  # rebuilds the car
        assert vehicle.name == car and is_held_out(vehicle)
        assert (report / "physics" / f"{car}.single_track.yaml").is_file()
        assert (report / "physics" / f"{car}.ukf.yaml").is_file()

    readme = (report / "README.md").read_text()
    headings = ("## MAE [deg] per car × μ", "## RMSE [deg]", "## R²", "## max |error|",
                "## MAE [deg] per car (pooled over μ)", "## Pass / fail (issue 8)")  # fmt: skip
    for heading in headings:
        assert heading in readme
    assert "**mean over cells**" in readme and "sideslip-benchmark --data" in readme
    for verdict in ("**tiny paper** (with Y_v)", "**tiny measurable** (measurable)"):
        line = next(x for x in readme.splitlines() if x.startswith(f"- {verdict}"))
        assert "PASS" in line or "FAIL" in line
    assert "not the full benchmark" in readme  # 4 of 108 runs: said so beside the verdicts


def test_every_estimator_is_scored_on_the_same_samples_of_a_run(report: Path, held_out_bags):
    for run in _results(report)["runs"]:
        bag_samples = len(read_bag(held_out_bags / run["run"]).samples)
        counts = {m["samples"] for m in run["estimators"].values()}
        # Every sample with a full window behind it, and none lost to the physics filters'
        # input checks (the steering limit follows the car).
        assert counts == {run["samples"]} == {bag_samples - 99}
        assert all(m["without_estimate"] == 0 for m in run["estimators"].values())


def test_a_cell_pools_the_samples_of_its_runs_and_overall_is_the_mean_over_cells(report: Path):
    res = _results(report)
    for cell in res["cells"]:
        runs = [r for r in res["runs"] if (r["vehicle"], r["mu"]) == (cell["vehicle"], cell["mu"])]
        assert cell["runs"] == len(runs)
        for name, m in cell["estimators"].items():
            n = [r["estimators"][name]["samples"] for r in runs]
            mae = [r["estimators"][name]["mae_deg"] for r in runs]
            assert m["samples"] == sum(n)
            assert m["mae_deg"] == pytest.approx(np.dot(n, mae) / sum(n), rel=1e-9)
            assert m["max_abs_deg"] == max(r["estimators"][name]["max_abs_deg"] for r in runs)
    for name, overall in res["overall_mean_over_cells"].items():
        cells = [c["estimators"][name]["mae_deg"] for c in res["cells"]]
        assert overall["mae_deg"] == pytest.approx(np.mean(cells), rel=1e-12)


def test_a_bag_of_a_car_that_is_not_held_out_is_refused(sim_bag_dir: Path, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["--data", str(sim_bag_dir), "--out", str(out), "--no-default-models",
                 "--quiet"]) == 2  # fmt: skip
    err = capsys.readouterr().err
    assert "is not a held-out car" in err and "paper_sedan" in err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    assert not out.exists()


def test_a_non_empty_out_is_refused_without_force(held_out_bags: Path, tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    assert main(["--data", str(held_out_bags), "--out", str(out), "--quiet"]) == 2
    assert "--force" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["mine.txt"]


def test_force_replaces_the_benchmark_files_and_keeps_the_others(held_out_bags: Path, tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    (out / "results.json").write_text("{}")
    args = ["--data", str(held_out_bags), "--out", str(out), "--quiet", "--no-default-models"]
    assert main([*args, "--force", "--runs-limit", "1"]) == 0
    assert (out / "mine.txt").read_text() == "keep"
    assert _results(out)["runs_scored"] == 3


def test_runs_limit_keeps_the_first_runs_of_every_cell(held_out_bags: Path, tmp_path):
    out = tmp_path / "out"
    args = ["--data", str(held_out_bags), "--out", str(out), "--quiet", "--no-default-models"]
    assert main([*args, "--runs-limit", "1"]) == 0
    runs = [(r["vehicle"], r["mu"], r["kind"]) for r in _results(out)["runs"]]
    assert runs == [PICKS[0], PICKS[2], PICKS[3]]  # scen2 comes before sweep_steer


def test_a_missing_data_folder_is_refused_with_a_hint_to_generate(tmp_path, capsys):
    args = ["--data", str(tmp_path / "nothing"), "--out", str(tmp_path / "out"), "--quiet"]
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "nothing" in err and "--generate" in err and "Traceback" not in err


def test_an_unreadable_model_file_is_refused(held_out_bags: Path, tmp_path, capsys):
    bad = tmp_path / "bad.safetensors"
    bad.write_bytes(b"not a model")
    args = ["--data", str(held_out_bags), "--out", str(tmp_path / "out"), "--quiet"]
    assert main([*args, "--model", f"bad={bad}"]) == 2
    err = capsys.readouterr().err
    assert "bad.safetensors" in err and "Traceback" not in err


def test_models_with_different_windows_are_refused(
    held_out_bags: Path, tiny_models: dict[str, Path], tmp_path, capsys
):
    from sideslip_training.export import export_model, load_model

    net, meta = load_model(tiny_models["paper"])
    other = export_model(
        tmp_path / "w50.safetensors", net, dataclasses.replace(meta, window_steps=50)
    )
    args = ["--data", str(held_out_bags), "--out", str(tmp_path / "out"), "--quiet"]
    assert main([*args, "--model", str(tiny_models["paper"]), "--model", f"w50={other}"]) == 2
    assert "different windows" in capsys.readouterr().err


def test_physics_params_of_an_unknown_parameter_are_refused(held_out_bags: Path, tmp_path, capsys):
    params = tmp_path / "tuned.yaml"
    params.write_text("ukf:\n  no_such_sigma: 1.0\n")
    args = ["--data", str(held_out_bags), "--out", str(tmp_path / "out"), "--quiet"]
    assert main([*args, "--physics-params", str(params)]) == 2
    assert "no_such_sigma" in capsys.readouterr().err


def test_a_missing_ukf_backend_drops_its_column_with_a_note(
    held_out_bags: Path, tmp_path, capsys, monkeypatch
):
    from sideslip_estimator import backends

    monkeypatch.delitem(backends.BACKENDS, "ukf")
    out = tmp_path / "out"
    args = ["--data", str(held_out_bags), "--out", str(out), "--quiet", "--no-default-models"]
    assert main([*args, "--runs-limit", "1"]) == 0
    res = _results(out)
    assert UKF not in res["estimators"] and SINGLE_TRACK in res["estimators"]
    assert any(n.startswith(f"{UKF}: skipped") for n in res["notes"])
    assert f"{UKF}: skipped" in capsys.readouterr().err


def test_generate_refuses_a_data_folder_that_is_not_held_out(sim_bag_dir: Path, tmp_path, capsys):
    data = tmp_path / "data"
    shutil.copytree(sim_bag_dir, data)
    before = sorted(p.name for p in data.iterdir())
    args = ["--data", str(data), "--generate", "--out", str(tmp_path / "out"), "--quiet"]
    assert main(args) == 2
    assert "not a held-out folder" in capsys.readouterr().err
    assert sorted(p.name for p in data.iterdir()) == before  # nothing deleted


def test_generate_writes_the_held_out_bags_then_scores_them(tmp_path, monkeypatch):
    picks = [("heldout_van_fwd", 0.4, "scen1"), ("heldout_ev_awd", 1.0, "sweep_steer")]
    runs = _short_held_out_runs(picks)
    monkeypatch.setattr(benchmark_data, "held_out_runs", lambda: runs)
    data, out = tmp_path / "data", tmp_path / "out"
    args = ["--data", str(data), "--generate", "--out", str(out), "--quiet", "--no-default-models"]
    assert main([*args, "--jobs", "1"]) == 0
    index = json.loads((data / "index.json").read_text())
    assert index["preset"] == "held-out" and index["noise"] == "paper" and index["seed"] == 0
    assert {(r["vehicle"], r["mu"], r["kind"]) for r in _results(out)["runs"]} == set(picks)


def test_a_network_gets_the_car_when_predict_run_takes_one(held_out_bags: Path, monkeypatch):
    """Vehicle-conditioned models: predict_run(model, meta, run, vehicle=VehicleParams)."""
    from sideslip_sim.vehicle import VehicleParams
    from sideslip_training import evaluate

    seen = []

    def predict_run(model, meta, run, *, vehicle=None, mirror_average=False):
        seen.append(vehicle)
        return np.zeros(len(run.samples) - meta.window_steps + 1)

    monkeypatch.setattr(evaluate, "predict_run", predict_run)
    run = benchmark_data.load_held_out(held_out_bags, progress=False)[0]
    net = benchmark_estimators.load_networks([], shipped=True)[0]
    benchmark_estimators.predict(net, run)
    assert isinstance(seen[0], VehicleParams) and seen[0].name == run.vehicle_name


def test_both_ways_scores_each_run_and_its_mirror_image_in_its_cell(
    held_out_bags: Path, tiny_models: dict[str, Path], tmp_path: Path
) -> None:
    """With ``--both-ways`` every run is scored again turned the other way; the symmetric
    estimators (β = 0, the kinematics, the filters, a mirror-averaged network) err alike
    on both, so no figure can come from the side of the drive."""
    out = tmp_path / "both"
    code = main(
        [
            "--data", str(held_out_bags), "--out", str(out), "--jobs", "1", "--quiet",
            "--no-default-models", "--model", f"tiny={tiny_models['measurable']}",
            "--both-ways", "--mirror-average",
        ]
    )  # fmt: skip
    assert code == 0
    res = _results(out)
    runs = {r["run"]: r for r in res["runs"]}
    assert len(runs) == 2 * len(PICKS)
    assert res["both_ways"] and res["mirror_average"] == "yes"
    assert res["mirror_averaged"] == {"tiny": True}
    for name, run in runs.items():
        if name.endswith("~mirror"):
            continue
        twin = runs[name + "~mirror"]
        assert (twin["vehicle"], twin["mu"]) == (run["vehicle"], run["mu"])
        for label in (ZERO, KINEMATIC_RAW, KINEMATIC_MEAN, SINGLE_TRACK, UKF, "tiny"):
            a, b = run["estimators"][label]["mae_deg"], twin["estimators"][label]["mae_deg"]
            assert a == pytest.approx(b, rel=1e-6, abs=1e-9), label
    for cell in res["cells"]:
        assert cell["runs"] % 2 == 0
    readme = (out / "README.md").read_text()  # says what was scored, counted both ways
    assert f"{len(runs)} runs of the 216 of the full benchmark: each run and its mirror" in readme
    assert "averaged with its own mirror image" in readme


@pytest.mark.parametrize(
    ("context", "says"),
    [
        ({"mirror_average": "auto", "mirror_averaged": {"a": True, "b": True}}, "Every network is"),
        ({"mirror_average": "auto", "mirror_averaged": {"a": True, "b": False}}, "a is averaged"),
        (
            {"mirror_average": "yes", "mirror_averaged": {"a": True, "b": True, "c": False}},
            "a and b are averaged with their own mirror images",
        ),
        ({"mirror_average": "no", "mirror_averaged": {"a": False}}, "No network is averaged"),
        ({"mirror_average": True}, "Every network is"),  # a report of before 2026-12-06
        ({"mirror_average": False}, ""),
    ],
)
def test_the_report_names_the_networks_it_averaged_with_their_mirror_image(context, says) -> None:
    from sideslip_training.benchmark_report import mirror_sentence

    sentence = mirror_sentence(context)
    assert says in sentence and (says or not sentence)
