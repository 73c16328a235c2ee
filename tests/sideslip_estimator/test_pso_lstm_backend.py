"""The pso_lstm back-end: the same β̂ as the trainer's network (bit for bit with the torch
engine, within 1e-6 rad with the streaming engine), from the artifact alone; refusals at
start-up; the registry does not import torch."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from importlib import resources
from pathlib import Path

import numpy as np
import pytest
import torch
from safetensors.numpy import save_file

from sideslip_estimator.backends import BACKENDS, BackendError, create_backend
from sideslip_estimator.backends.model_files import SHIPPED_MODEL
from sideslip_estimator.backends.pso_lstm import DEFAULT_SIGMA_RAD, PsoLstmBackend
from sideslip_msgs_py.artifact import (
    METADATA_KEY,
    ModelMetadata,
    denormalize_beta,
    read_artifact,
    zscore,
)
from sideslip_msgs_py.features import FEATURE_SETS, channel_indices
from sideslip_training.export import export_model, load_model
from sideslip_training.model import ModelConfig, SideslipNet

torch.set_num_threads(1)
WINDOW = 100
STEP_NS = 2_500_000


def write_model(
    path: Path,
    architecture: str = "lstm",
    feature_set: str = "paper",
    *,
    hidden: int = 16,
    layers: int = 1,
    window: int = WINDOW,
    metrics: dict | None = None,
    seed: int = 0,
    uncertainty: dict | None = None,
) -> Path:
    features = FEATURE_SETS[feature_set]
    torch.manual_seed(seed)
    net = SideslipNet(ModelConfig(architecture, len(features), hidden, layers))
    # Statistics of the synthetic rows below, so the network sees inputs of order 1.
    stats = {
        "x_v_mps": (20.0, 2.0),
        "y_v_mps": (0.0, 0.5),
        "x_a_mps2": (0.0, 0.3),
        "y_a_mps2": (0.0, 4.0),
        "yaw_rate_radps": (0.0, 0.2),
        "stl_m": (0.0, 0.02),
    }
    meta = ModelMetadata(
        architecture=architecture,
        hidden_units=hidden,
        layers=layers,
        features=features,
        window_steps=window,
        dt_s=0.0025,
        feature_mean=tuple(stats[f][0] for f in features),
        feature_std=tuple(stats[f][1] for f in features),
        beta_mean=0.002,
        beta_std=0.03,
        training_data_digest="sha256:0123456789abcdef",
        metrics={"val_rmse_deg": 0.4} if metrics is None else metrics,
        uncertainty=uncertainty,
    )
    return export_model(path, net, meta)


def make_rows(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A read-only window like SampleWindow.rows(): CHANNELS columns, oldest first."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * STEP_NS * 1e-9
    rows = np.stack(
        [
            20.0 + rng.normal(0, 0.3, n),
            0.5 * np.sin(3.0 * t) + rng.normal(0, 0.3, n),
            rng.normal(0, 0.3, n),
            4.0 * np.sin(3.0 * t + 0.2),
            0.2 * np.sin(3.0 * t + 0.2),
            0.02 * np.sin(3.0 * t),
        ],
        axis=1,
    )
    rows.flags.writeable = False
    return rows, np.arange(n, dtype=np.int64) * STEP_NS


def reference_beta(path: Path, rows: np.ndarray) -> float:
    """What the trainer's network gives on the newest window (batch of one)."""
    net, meta = load_model(path)
    x = zscore(rows[-meta.window_steps :, channel_indices(meta.features)], *_stats(meta))
    with torch.inference_mode():
        y = net(torch.from_numpy(x)[None])
    return denormalize_beta(y.item(), meta)


def _stats(meta: ModelMetadata) -> tuple[np.ndarray, np.ndarray]:
    return np.asarray(meta.feature_mean), np.asarray(meta.feature_std)


# --- same output as the network it was exported from ------------------------------------------


MODELS = [("lstm", "paper", 1), ("lstm", "measurable", 2), ("bilstm", "measurable", 1)]


@pytest.mark.parametrize(("architecture", "feature_set", "layers"), MODELS)
def test_the_torch_engine_equals_the_trained_network_bit_for_bit(
    tmp_path: Path, architecture: str, feature_set: str, layers: int
) -> None:
    path = write_model(tmp_path / "m.safetensors", architecture, feature_set, layers=layers)
    backend = create_backend("pso_lstm", {"model_file": str(path), "engine": "torch"}, WINDOW)
    rows, stamps = make_rows(WINDOW + 40, seed=1)
    for end in (WINDOW, WINDOW + 17, WINDOW + 40):  # successive windows reuse the buffers
        est = backend.update(rows[end - WINDOW : end], stamps[end - WINDOW : end])
        assert est is not None
        assert est.beta_rad == reference_beta(path, rows[:end])
        assert math.isfinite(est.beta_rad) and est.beta_rad != 0.0


@pytest.mark.parametrize("engine", ["numba", "numpy"])
@pytest.mark.parametrize(("architecture", "feature_set", "layers"), MODELS)
def test_the_streaming_engine_equals_the_trained_network_within_1e_6_rad(
    tmp_path: Path, architecture: str, feature_set: str, layers: int, engine: str
) -> None:
    path = write_model(tmp_path / "m.safetensors", architecture, feature_set, layers=layers)
    backend = create_backend("pso_lstm", {"model_file": str(path), "engine": engine}, WINDOW)
    assert backend.engine == engine
    rows, stamps = make_rows(WINDOW + 60, seed=1)
    # As the estimator calls it: one new row per call, the window growing to full.
    for end in range(1, WINDOW + 40):
        est = backend.update(rows[max(0, end - WINDOW) : end], stamps[max(0, end - WINDOW) : end])
        assert (est is None) == (end < WINDOW)
        if end in (WINDOW, WINDOW + 17, WINDOW + 39):
            assert abs(est.beta_rad - reference_beta(path, rows[:end])) <= 1e-6
    # A caller that skips rows: the engine refills from the window, still the window's β̂.
    end = WINDOW + 60
    est = backend.update(rows[end - WINDOW : end], stamps[end - WINDOW : end])
    assert abs(est.beta_rad - reference_beta(path, rows[:end])) <= 1e-6
    # After reset nothing until the window is full again.
    backend.reset()
    assert backend.update(rows[:1], stamps[:1]) is None


def test_no_estimate_until_the_window_is_full(tmp_path: Path) -> None:
    backend = PsoLstmBackend({"model_file": str(write_model(tmp_path / "m.safetensors"))}, WINDOW)
    rows, stamps = make_rows(WINDOW - 1)
    assert backend.update(rows, stamps) is None
    assert backend.update(rows[:1], stamps[:1]) is None
    backend.reset()


def test_variance_is_the_validation_rmse_squared_else_the_stated_default(tmp_path: Path) -> None:
    rows, stamps = make_rows(WINDOW)
    with_rmse = write_model(tmp_path / "a.safetensors", metrics={"val_rmse_deg": 0.4})
    est = PsoLstmBackend({"model_file": str(with_rmse)}, WINDOW).update(rows, stamps)
    assert est is not None and est.variance_rad2 == pytest.approx(math.radians(0.4) ** 2)
    without = write_model(tmp_path / "b.safetensors", metrics={})
    est = PsoLstmBackend({"model_file": str(without)}, WINDOW).update(rows, stamps)
    assert est is not None and est.variance_rad2 == DEFAULT_SIGMA_RAD**2


def test_sigma_widens_while_the_window_reaches_beyond_the_fitted_recordings(
    tmp_path: Path,
) -> None:
    """A model fine-tuned on one car's gentle recordings: its own scale while the
    window's driving is like theirs, the wider one while any sample of it is not."""
    from sideslip_msgs_py.uncertainty import FitRange, Uncertainty

    unc = Uncertainty(
        (1e-8, 2.7e-5, 1.2e-7, 4.8e-4), 0.5, fit_range=FitRange(5.0, 1.0, 2.0, WINDOW)
    )
    path = write_model(tmp_path / "fitted.safetensors", uncertainty=unc.to_dict())
    rows, stamps = make_rows(WINDOW)  # |a_y| ≤ 4 m/s²: inside
    own = unc.variance_of(*(float(rows[-1, i]) for i in (0, 3, 4)))
    est = PsoLstmBackend({"model_file": str(path)}, WINDOW).update(rows, stamps)
    assert est is not None and est.variance_rad2 == pytest.approx(own, rel=1e-12)
    assert not est.beyond_fit_range
    rows = rows.copy()
    rows[0, 3] = 7.0  # the oldest sample of the window at 7 m/s²: beyond
    est = PsoLstmBackend({"model_file": str(path)}, WINDOW).update(rows, stamps)
    assert est is not None and est.variance_rad2 == pytest.approx(own * 16.0, rel=1e-12)
    assert est.beyond_fit_range  # the node's status counts it (sigma_widened)


def test_beyond_the_fitted_recordings_the_start_models_estimate_and_sigma_are_published(
    tmp_path: Path,
) -> None:
    """beyond_fit_range: start (auto when the start model is found) publishes, while the
    window reaches beyond the fitted recordings, what the start model alone would; model
    keeps the fitted model's estimate with σ widened."""
    from sideslip_msgs_py.uncertainty import FitRange, Uncertainty

    coefficients = (1e-8, 2.7e-5, 1.2e-7, 4.8e-4)
    start = write_model(
        tmp_path / "start.safetensors", seed=1, uncertainty=Uncertainty(coefficients, 1.0).to_dict()
    )
    # Recordings under 5 m/s² (gentle): auto hands over; beyond them it would not.
    unc = Uncertainty(coefficients, 0.5, fit_range=FitRange(4.5, 1.0, 2.0, WINDOW))
    fitted = write_model(tmp_path / "fitted.safetensors", uncertainty=unc.to_dict())
    files = {"model_file": str(fitted), "start_model_file": str(start)}
    gated = PsoLstmBackend(files, WINDOW)
    varied = Uncertainty(coefficients, 0.5, fit_range=FitRange(6.0, 1.0, 2.0, WINDOW))
    near_limit = write_model(tmp_path / "varied.safetensors", uncertainty=varied.to_dict())
    auto = PsoLstmBackend({**files, "model_file": str(near_limit)}, WINDOW)
    assert "beyond its recordings" not in auto.model_id
    assert (
        "beyond its recordings"
        in PsoLstmBackend(
            {**files, "model_file": str(near_limit), "beyond_fit_range": "start"}, WINDOW
        ).model_id
    )
    assert "beyond its recordings: start.safetensors's estimate" in gated.model_id
    own = PsoLstmBackend({**files, "beyond_fit_range": "model"}, WINDOW)
    alone = PsoLstmBackend({"model_file": str(start)}, WINDOW)
    rows, stamps = make_rows(WINDOW)  # |a_y| ≤ 4 m/s²: inside
    inside, mine = gated.update(rows, stamps), own.update(rows, stamps)
    assert inside == mine and inside is not None and not inside.beyond_fit_range
    rows = rows.copy()
    rows[0, 3] = 7.0  # the oldest sample at 7 m/s²: beyond both ranges
    beyond, mine, theirs = (b.update(rows, stamps) for b in (gated, own, alone))
    assert beyond is not None and theirs is not None and mine is not None
    assert (beyond.beta_rad, beyond.variance_rad2) == (theirs.beta_rad, theirs.variance_rad2)
    assert beyond.beyond_fit_range and beyond.beta_rad != mine.beta_rad
    assert mine.beyond_fit_range  # model: its own estimate, σ widened


def test_a_start_model_on_the_same_filter_shares_it_and_publishes_what_it_alone_would(
    tmp_path: Path,
) -> None:
    """A residual on the UKF fine-tuned from the shipped ``fleet_ukf_measurable``: the
    filter runs once for both models, and beyond the range the estimate is the one the
    shipped model alone publishes, sample by sample."""
    import dataclasses

    import yaml

    from sideslip_estimator.backends.model_files import read_model
    from sideslip_msgs_py.artifact import write_artifact
    from sideslip_msgs_py.uncertainty import FitRange, Uncertainty
    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_sim.vehicle import load_vehicle

    tensors, meta, _ = read_model("fleet_ukf_measurable")
    unc = Uncertainty.from_dict(meta.uncertainty)
    unc = dataclasses.replace(unc, fit_range=FitRange(3.0, 0.08, 2 * unc.scale, WINDOW))
    provenance = {
        "init": "fleet_ukf_measurable.safetensors",
        "init_data": meta.training_data_digest,
    }
    desc = VehicleDescription.from_mapping(dataclasses.asdict(load_vehicle("paper_sedan")))
    # As sideslip-fit stores it: the fitted model holds the car, the shipped start not.
    fitted = write_artifact(
        tmp_path / "fitted.safetensors",
        tensors,
        dataclasses.replace(
            meta, uncertainty=unc.to_dict(), provenance=provenance, vehicle=desc.to_dict()
        ),
    )
    car = tmp_path / "car.yaml"
    car.write_text(yaml.safe_dump(desc.to_dict()))
    # paper_sedan lies outside the fleet's cars: the network's estimate all the same.
    files = {"observer_params_file": "paper_sedan", "outside_fleet": "network"}
    gated = PsoLstmBackend({"model_file": str(fitted), **files}, WINDOW)  # no vehicle_file
    assert gated._shared_observer
    alone = PsoLstmBackend(
        {"model_file": "fleet_ukf_measurable", "vehicle_file": str(car), **files}, WINDOW
    )
    rows, stamps = make_rows(3 * WINDOW, seed=4)  # |a_y| up to 4 m/s²: in and out of 3
    window = (slice(max(0, k + 1 - WINDOW), k + 1) for k in range(rows.shape[0]))
    beyond = 0
    for w in window:
        mine, theirs = gated.update(rows[w], stamps[w]), alone.update(rows[w], stamps[w])
        if mine is not None and mine.beyond_fit_range:
            assert theirs is not None and mine.beta_rad == theirs.beta_rad
            assert mine.variance_rad2 == theirs.variance_rad2
            beyond += 1
    assert beyond > 0


def test_beyond_fit_range_start_needs_a_range_and_a_start_model(tmp_path: Path) -> None:
    from sideslip_msgs_py.uncertainty import FitRange, Uncertainty

    coefficients = (1e-8, 2.7e-5, 1.2e-7, 4.8e-4)
    plain = write_model(
        tmp_path / "plain.safetensors", uncertainty=Uncertainty(coefficients, 1.0).to_dict()
    )
    with pytest.raises(BackendError, match="records no range of recordings"):
        PsoLstmBackend({"model_file": str(plain), "beyond_fit_range": "start"}, WINDOW)
    unc = Uncertainty(coefficients, 0.5, fit_range=FitRange(4.0, 1.0, 2.0, WINDOW))
    fitted = write_model(tmp_path / "fitted.safetensors", uncertainty=unc.to_dict())
    with pytest.raises(BackendError, match=r"set pso_lstm\.start_model_file"):
        PsoLstmBackend({"model_file": str(fitted), "beyond_fit_range": "start"}, WINDOW)
    # auto without a start model to find: the fitted model's own estimate, σ widened.
    assert (
        "beyond its recordings" not in PsoLstmBackend({"model_file": str(fitted)}, WINDOW).model_id
    )
    other = write_model(tmp_path / "other.safetensors", "lstm", "measurable")
    files = {"model_file": str(fitted), "start_model_file": str(other)}
    with pytest.raises(BackendError, match=r"beyond_fit_range start model .*inputs differ"):
        PsoLstmBackend({**files, "beyond_fit_range": "start"}, WINDOW)
    # auto: the fitted model's own estimate, and a caveat the status WARNs with.
    fallback = PsoLstmBackend(files, WINDOW)
    assert "beyond its recordings" not in fallback.model_id
    assert any("inputs differ" in c and "σ widened" in c for c in fallback.caveats)
    with pytest.raises(BackendError, match="beyond_fit_range must be one of"):
        PsoLstmBackend({"model_file": str(fitted), "beyond_fit_range": "never"}, WINDOW)


def test_the_start_model_is_the_shipped_one_the_file_names_with_its_training_data() -> None:
    import dataclasses

    from sideslip_estimator.backends.model_files import read_model, start_model_name

    shipped = read_model("fleet_lstm_paper")[1]
    named = {"init": "fleet_lstm_paper.safetensors", "init_data": shipped.training_data_digest}
    assert start_model_name(dataclasses.replace(shipped, provenance=named)) == "fleet_lstm_paper"
    for provenance in (
        {**named, "init_data": "sha256:another"},  # the shipped model was replaced since
        {"init": "my_car.safetensors", "init_data": shipped.training_data_digest},
        {},
    ):
        assert start_model_name(dataclasses.replace(shipped, provenance=provenance)) is None


def test_model_id_names_the_file_architecture_and_data(tmp_path: Path) -> None:
    path = write_model(tmp_path / "paper_bi.safetensors", "bilstm", hidden=8, layers=2)
    backend = PsoLstmBackend({"model_file": str(path), "threads": 1}, WINDOW)
    assert backend.model_id.startswith("pso_lstm(paper_bi.safetensors: bilstm 2x8")
    assert "data sha256:01234" in backend.model_id
    assert backend.dt_s == 0.0025
    assert BACKENDS["pso_lstm"] is PsoLstmBackend


# --- refusals at start-up -----------------------------------------------------------------------


def test_a_window_other_than_the_models_is_refused(tmp_path: Path) -> None:
    path = write_model(tmp_path / "m.safetensors", window=50)
    with pytest.raises(BackendError, match=r"reads 50-step windows .* window_steps is 100"):
        PsoLstmBackend({"model_file": str(path)}, WINDOW)


def test_a_missing_file_is_refused_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "absent.safetensors"
    with pytest.raises(BackendError, match=r"pso_lstm\.model_file: .*absent\.safetensors: no such"):
        PsoLstmBackend({"model_file": str(path)}, WINDOW)


def test_a_feature_the_window_lacks_is_refused(tmp_path: Path) -> None:
    good = write_model(tmp_path / "m.safetensors", feature_set="measurable")
    tensors, meta = read_artifact(good)
    header = meta.to_header()
    data = json.loads(header[METADATA_KEY])
    data["features"][0] = "wheel_speed_mps"
    header[METADATA_KEY] = json.dumps(data)
    bad = tmp_path / "bad.safetensors"
    save_file(tensors, bad, metadata=header)
    unknown = r"bad\.safetensors: .*unknown model input\(s\) \['wheel_speed_mps'\]"
    with pytest.raises(BackendError, match=unknown):
        PsoLstmBackend({"model_file": str(bad)}, WINDOW)


def test_a_file_that_is_not_a_model_is_refused(tmp_path: Path) -> None:
    path = tmp_path / "notes.safetensors"
    path.write_text("not a model")
    with pytest.raises(BackendError, match=r"notes\.safetensors: not a safetensors file"):
        PsoLstmBackend({"model_file": str(path)}, WINDOW)


def test_the_default_is_the_shipped_model_or_a_clear_error() -> None:
    shipped = resources.files("sideslip_estimator").joinpath(SHIPPED_MODEL)
    if shipped.is_file():
        _, meta = read_artifact(Path(str(shipped)))
        backend = PsoLstmBackend({}, meta.window_steps)
        assert "(shipped)" in backend.model_id
    else:
        with pytest.raises(BackendError, match=r"no model is shipped yet.*sideslip-train"):
            PsoLstmBackend({}, WINDOW)


def test_the_default_with_the_cars_ukf_file_is_the_model_anchored_on_the_ukf() -> None:
    backend = PsoLstmBackend({"observer_params_file": "paper_sedan"}, WINDOW)
    assert backend.model_id.startswith("pso_lstm(fleet_ukf_paper.safetensors (shipped)")
    assert "observer ukf(paper_sedan)" in backend.model_id
    assert backend.meta.needs_observer and not PsoLstmBackend({}, WINDOW).meta.needs_observer


@pytest.mark.parametrize(
    ("values", "match"),
    [
        ({"threads": 0}, r"pso_lstm\.threads must be >= 1"),
        ({"threads": 1.5}, r"pso_lstm\.threads must be a int"),
        ({"model_file": 3}, r"pso_lstm\.model_file must be a string"),
        ({"model": "x"}, r"unknown parameter"),
    ],
)
def test_invalid_parameters_are_refused(values: dict, match: str) -> None:
    with pytest.raises(BackendError, match=match):
        PsoLstmBackend(values, WINDOW)


# --- import weight --------------------------------------------------------------------------------


def test_the_streaming_engine_runs_the_shipped_default_without_torch() -> None:
    code = (
        "import sys\n"
        "from sideslip_estimator.backends import create_backend\n"
        "b = create_backend('pso_lstm', {}, 100)\n"
        "assert b.engine == 'numba'\n"
        "print('torch' in sys.modules)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == "False"


def test_without_numba_the_default_engine_falls_back_to_numpy() -> None:
    code = (
        "import sys\n"
        "sys.modules['numba'] = None  # import numba now raises ImportError\n"
        "from sideslip_estimator.backends import create_backend\n"
        "b = create_backend('pso_lstm', {}, 100)\n"
        "print(b.engine, 'engine numpy' in b.model_id)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == "numpy True"


def test_importing_the_backends_does_not_import_torch() -> None:
    code = (
        "import sys\n"
        "import sideslip_estimator.backends as b\n"
        "assert 'pso_lstm' in b.BACKENDS\n"
        "print(sorted(m for m in ('torch', 'safetensors') if m in sys.modules))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=60
    )
    assert out.stdout.strip() == "[]"


def test_the_shipped_default_publishes_a_sigma_that_follows_the_driving() -> None:
    """Its uncertainty model: wider at low speed and in hard cornering than cruising."""
    from sideslip_estimator.backends.pso_lstm import PsoLstmBackend
    from sideslip_msgs_py.features import CHANNELS

    backend = create_backend("pso_lstm", {}, 100)
    assert isinstance(backend, PsoLstmBackend) and backend.meta.uncertainty is not None

    def variance(x_v: float, y_a: float, r: float) -> float:
        rows = np.zeros((100, len(CHANNELS)))
        rows[:, CHANNELS.index("x_v_mps")] = x_v
        rows[:, CHANNELS.index("y_a_mps2")] = y_a
        rows[:, CHANNELS.index("yaw_rate_radps")] = r
        return backend._variance(rows)[0]

    cruising = variance(30.0, 0.0, 0.0)
    assert variance(5.0, 0.0, 0.0) > 10 * cruising
    assert variance(30.0, 8.0, 0.0) > cruising  # a_y without the matching yaw rate: β̇ ≠ 0


def test_a_car_file_made_from_a_description_gets_the_models_sigma_for_such_files(
    tmp_path: Path,
) -> None:
    """The same model and car: with the file marked ``axles_from: description`` the node
    publishes the σ calibrated with described files, and says so in its model id."""
    import dataclasses

    import yaml

    from sideslip_estimator.backends.ukf_model import UkfParams
    from sideslip_estimator.inputs import X_V, Y_A, YAW_RATE
    from sideslip_msgs_py.artifact import write_artifact
    from sideslip_msgs_py.uncertainty import Uncertainty
    from sideslip_msgs_py.vehicle_description import VehicleDescription
    from sideslip_sim.vehicle import load_vehicle
    from sideslip_training.init_model import resolve

    tensors, meta = read_artifact(resolve("fleet_ukf_measurable"))
    own = Uncertainty.from_dict(meta.uncertainty)
    described = Uncertainty((0.0, 3e-5, 2e-7, 5e-4), 2.0 * own.scale)
    both = dataclasses.replace(own, described=described)
    model = write_artifact(
        tmp_path / "m.safetensors", tensors, dataclasses.replace(meta, uncertainty=both.to_dict())
    )
    car = dataclasses.asdict(UkfParams.load("compact_rwd"))
    vehicle = tmp_path / "car.yaml"
    desc = VehicleDescription.from_mapping(dataclasses.asdict(load_vehicle("compact_rwd")))
    vehicle.write_text(yaml.safe_dump(desc.to_dict()))
    files = {}
    for source in ("vehicle", "description"):
        path = tmp_path / f"{source}.ukf.yaml"
        path.write_text(yaml.safe_dump({**car, "axles_from": source}))
        files[source] = PsoLstmBackend(
            {
                "model_file": str(model),
                "observer_params_file": str(path),
                "vehicle_file": str(vehicle),
                "outside_fleet": "network",
            },
            WINDOW,
        )
    assert "σ for a described car file" in files["description"].model_id
    # paper_sedan lies outside the model's training cars: with outside_fleet prior the
    # UKF's own estimate and σ are published, and the id does not claim the model's.
    sedan = tmp_path / "sedan.ukf.yaml"
    params = dataclasses.asdict(UkfParams.load("paper_sedan"))
    sedan.write_text(yaml.safe_dump({**params, "axles_from": "description"}))
    ukf_alone = PsoLstmBackend(
        {
            "model_file": str(model),
            "observer_params_file": str(sedan),
            "vehicle_file": str(vehicle),
            "outside_fleet": "prior",
        },
        WINDOW,
    )
    assert "the UKF's estimate" in ukf_alone.model_id and "σ for" not in ukf_alone.model_id
    assert "described" not in files["vehicle"].model_id
    rows, stamps = make_rows(2 * WINDOW, seed=2)
    seen = 0
    for k in range(WINDOW, rows.shape[0] + 1):
        w = slice(k - WINDOW, k)
        mine, plain = (
            files["description"].update(rows[w], stamps[w]),
            files["vehicle"].update(rows[w], stamps[w]),
        )
        if mine is None:
            continue
        assert plain is not None and mine.beta_rad == plain.beta_rad  # the same filter
        x_v, a_y, r = (float(rows[k - 1, i]) for i in (X_V, Y_A, YAW_RATE))
        assert mine.variance_rad2 == pytest.approx(described.variance_of(x_v, a_y, r))
        assert plain.variance_rad2 == pytest.approx(own.variance_of(x_v, a_y, r))
        seen += 1
    assert seen > 0
