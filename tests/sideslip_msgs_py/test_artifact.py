"""The model artifact format: round trip, tensor layout, and every refusal naming the file."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from safetensors.numpy import save_file

from sideslip_msgs_py.artifact import (
    FORMAT_VERSION,
    METADATA_KEY,
    VERSION_KEY,
    ArtifactError,
    ArtifactExistsError,
    ModelMetadata,
    denormalize_beta,
    expected_tensors,
    read_artifact,
    write_artifact,
    zscore,
)
from sideslip_msgs_py.errors import ContractError
from sideslip_msgs_py.features import CHANNELS, FEATURE_SETS


def make_meta(**changes: object) -> ModelMetadata:
    features = changes.pop("features", FEATURE_SETS["measurable"])
    n = len(features)  # type: ignore[arg-type]
    values: dict[str, object] = {
        "architecture": "lstm",
        "hidden_units": 4,
        "layers": 1,
        "features": features,
        "window_steps": 100,
        "dt_s": 0.0025,
        "feature_mean": tuple(0.1 * i for i in range(n)),
        "feature_std": tuple(1.0 + i for i in range(n)),
        "beta_mean": 0.001,
        "beta_std": 0.02,
        "training_data_digest": "sha256:abc",
        "metrics": {"val_rmse_deg": 0.3, "per_scenario": {"dlc": [0.1, 0.2]}},
        "pso": {"hidden_units": 4, "log10_lr": -2.5},
        "created_utc": "2026-01-02T03:04:05Z",
        "provenance": {"command": "sideslip-train --model lstm", "sideslip_training": "0.1.0"},
    }
    values.update(changes)
    return ModelMetadata(**values)  # type: ignore[arg-type]


def random_tensors(meta: ModelMetadata, seed: int = 0) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {
        name: rng.normal(0.0, 0.3, shape).astype(np.float32)
        for name, shape in expected_tensors(meta).items()
    }


def raw_file(path: Path, tensors: dict[str, np.ndarray], header: dict[str, str] | None) -> Path:
    """Write a safetensors file bypassing write_artifact's checks (to test the reader)."""
    save_file(tensors, path, metadata=header)
    return path


# --- layout ---------------------------------------------------------------------------------------


def test_expected_tensors_follow_torch_lstm_state_dict_naming() -> None:
    meta = make_meta(hidden_units=8, layers=2, features=CHANNELS)
    assert expected_tensors(meta) == {
        "lstm.weight_ih_l0": (32, 6),
        "lstm.weight_hh_l0": (32, 8),
        "lstm.bias_ih_l0": (32,),
        "lstm.bias_hh_l0": (32,),
        "lstm.weight_ih_l1": (32, 8),
        "lstm.weight_hh_l1": (32, 8),
        "lstm.bias_ih_l1": (32,),
        "lstm.bias_hh_l1": (32,),
        "head.weight": (1, 8),
        "head.bias": (1,),
    }


def test_bilstm_has_reverse_tensors_and_upper_layers_read_both_directions() -> None:
    shapes = expected_tensors(make_meta(architecture="bilstm", hidden_units=8, layers=2))
    assert shapes["lstm.weight_ih_l0_reverse"] == (32, 5)
    assert shapes["lstm.weight_ih_l1"] == shapes["lstm.weight_ih_l1_reverse"] == (32, 16)
    assert shapes["head.weight"] == (1, 16)
    assert len(shapes) == 2 * 2 * 4 + 2


def test_header_holds_the_version_and_the_metadata_as_json(tmp_path: Path) -> None:
    meta = make_meta()
    path = write_artifact(tmp_path / "m.safetensors", random_tensors(meta), meta)
    import safetensors

    with safetensors.safe_open(path, framework="numpy") as f:
        header = f.metadata()
    assert header[VERSION_KEY] == str(FORMAT_VERSION) == "1"
    data = json.loads(header[METADATA_KEY])
    assert data["features"] == list(FEATURE_SETS["measurable"])
    assert data["metrics"]["val_rmse_deg"] == 0.3


# --- round trip -----------------------------------------------------------------------------------


def test_round_trip_gives_the_same_tensors_and_metadata(tmp_path: Path) -> None:
    meta = make_meta(architecture="bilstm", layers=2)
    tensors = random_tensors(meta)
    path = write_artifact(tmp_path / "sub" / "m.safetensors", tensors, meta)
    got, got_meta = read_artifact(path)
    assert got_meta == meta
    assert list(got) == list(expected_tensors(meta))
    for name, t in tensors.items():
        assert got[name].dtype == np.float32
        np.testing.assert_array_equal(got[name], t)
    assert not list(path.parent.glob(".*tmp")), "the temporary file is renamed away"


def test_metadata_normalises_numpy_and_tuples_to_what_json_gives_back(tmp_path: Path) -> None:
    meta = make_meta(
        feature_mean=np.arange(5, dtype=np.float32),
        dt_s=np.float64(0.0025),
        hidden_units=np.int64(4),
        metrics={"val_rmse_deg": np.float32(0.5), "bounds": (1, 2)},
    )
    assert meta.feature_mean == (0.0, 1.0, 2.0, 3.0, 4.0)
    assert type(meta.hidden_units) is int
    assert meta.metrics == {"val_rmse_deg": 0.5, "bounds": [1, 2]}
    path = write_artifact(tmp_path / "m.safetensors", random_tensors(meta), meta)
    assert read_artifact(path)[1] == meta


def test_write_refuses_an_existing_file_unless_forced(tmp_path: Path) -> None:
    meta = make_meta()
    path = write_artifact(tmp_path / "m.safetensors", random_tensors(meta, 1), meta)
    with pytest.raises(ArtifactExistsError, match=r"m\.safetensors: exists"):
        write_artifact(path, random_tensors(meta, 2), meta)
    assert isinstance(ArtifactExistsError("x"), FileExistsError)
    write_artifact(path, random_tensors(meta, 2), meta, force=True)
    np.testing.assert_array_equal(
        read_artifact(path)[0]["head.bias"], random_tensors(meta, 2)["head.bias"]
    )


def test_write_checks_the_tensors_before_touching_the_file(tmp_path: Path) -> None:
    meta = make_meta()
    path = tmp_path / "m.safetensors"
    bad = random_tensors(meta)
    bad["head.weight"] = bad["head.weight"].astype(np.float64)
    with pytest.raises(ArtifactError, match=r"m\.safetensors: tensor head\.weight has dtype"):
        write_artifact(path, bad, meta)
    assert not list(tmp_path.iterdir())


def test_zscore_rounds_once_to_float32_and_beta_denormalises() -> None:
    x = np.array([[1.0, 2.0], [3.0, 5.0]])
    z = zscore(x, [1.0, 2.0], [2.0, 3.0])
    assert z.dtype == np.float32
    np.testing.assert_array_equal(z, np.array([[0.0, 0.0], [1.0, 1.0]], np.float32))
    meta = make_meta()
    assert denormalize_beta(2.0, meta) == 2.0 * 0.02 + 0.001


@settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    architecture=st.sampled_from(["lstm", "bilstm"]),
    hidden=st.integers(1, 9),
    layers=st.integers(1, 3),
    features=st.lists(st.sampled_from(CHANNELS), min_size=1, max_size=6, unique=True),
    window=st.integers(1, 200),
    std=st.floats(1e-6, 1e6),
)
def test_any_valid_shape_and_feature_list_round_trips(
    tmp_path: Path,
    architecture: str,
    hidden: int,
    layers: int,
    features: list[str],
    window: int,
    std: float,
) -> None:
    meta = make_meta(
        architecture=architecture,
        hidden_units=hidden,
        layers=layers,
        features=tuple(features),
        window_steps=window,
        feature_std=(std,) * len(features),
    )
    tensors = random_tensors(meta)
    path = write_artifact(tmp_path / "h.safetensors", tensors, meta, force=True)
    got, got_meta = read_artifact(path)
    assert got_meta == meta
    assert {k: v.shape for k, v in got.items()} == expected_tensors(meta)
    head_in = (2 if architecture == "bilstm" else 1) * hidden
    assert got["head.weight"].shape == (1, head_in)


# --- metadata refusals ----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"architecture": "gru"}, r"unknown architecture 'gru'"),
        ({"features": ("x_v_mps", "speed")}, r"unknown model input\(s\) \['speed'\]"),
        ({"features": ()}, r"features is empty"),
        ({"features": ("x_v_mps", "x_v_mps")}, r"duplicates"),
        ({"feature_mean": (0.0, 1.0)}, r"feature_mean has 2 values for 5 features"),
        ({"feature_std": (1.0,) * 6}, r"feature_std has 6 values for 5 features"),
        (
            {"feature_std": (1.0, 1.0, 0.0, 1.0, 1.0)},
            r"feature_std of y_a_mps2 must be finite and > 0",
        ),
        ({"feature_std": (1.0, -1.0, 1.0, 1.0, 1.0)}, r"feature_std of x_a_mps2"),
        ({"feature_std": (1.0, math.inf, 1.0, 1.0, 1.0)}, r"feature_std of x_a_mps2"),
        ({"feature_mean": (math.nan, 0, 0, 0, 0)}, r"feature_mean of x_v_mps must be finite"),
        ({"beta_std": 0.0}, r"beta_std must be a number, finite and > 0"),
        ({"beta_mean": math.nan}, r"beta_mean must be a number, finite"),
        ({"dt_s": -0.0025}, r"dt_s"),
        ({"hidden_units": 0}, r"hidden_units must be an integer >= 1"),
        ({"layers": 1.5}, r"layers must be an integer >= 1"),
        ({"window_steps": True}, r"window_steps must be an integer >= 1"),
        ({"format_version": 2}, r"unknown format_version 2"),
        ({"metrics": {"val_rmse_deg": -1.0}}, r"metrics\.val_rmse_deg must be a finite number"),
        ({"metrics": {"r2": math.nan}}, r"metrics must be strict JSON"),
        ({"pso": {"x": object()}}, r"pso must be strict JSON"),
        ({"provenance": "cmd"}, r"provenance must be a JSON object"),
        ({"prior": "ukf"}, r"observer \(the UKF's parameters\) must be given exactly when"),
        ({"observer": {"min_speed_mps": 3.0}}, r"observer .* must be given exactly when"),
        ({"prior": "ukf", "observer": "defaults"}, r"observer must be a JSON object"),
    ],
)
def test_invalid_metadata_is_refused_naming_the_field(changes: dict, match: str) -> None:
    with pytest.raises(ArtifactError, match=match):
        make_meta(**changes)


# --- reader refusals: each names the file ---------------------------------------------------------


def test_the_observers_settings_round_trip_with_a_model_anchored_on_it(tmp_path: Path) -> None:
    meta = make_meta(prior="ukf", observer={"min_speed_mps": 3.0, "tyre_relaxation": True})
    assert meta.needs_observer and not meta.needs_vehicle
    tensors = random_tensors(meta)
    write_artifact(tmp_path / "m.safetensors", tensors, meta)
    _, back = read_artifact(tmp_path / "m.safetensors")
    # A file that does not record the UKF's disturbance state (older than it) ran without.
    recorded = {"min_speed_mps": 3.0, "tyre_relaxation": True, "estimate_disturbance": False}
    assert back == meta and back.observer == recorded


def test_a_recorded_disturbance_setting_is_kept(tmp_path: Path) -> None:
    meta = make_meta(prior="ukf", observer={"estimate_disturbance": True})
    write_artifact(tmp_path / "m.safetensors", random_tensors(meta), meta)
    assert read_artifact(tmp_path / "m.safetensors")[1].observer == {"estimate_disturbance": True}


def test_artifact_error_is_a_contract_error() -> None:
    assert issubclass(ArtifactError, ContractError)


def test_missing_file_is_refused(tmp_path: Path) -> None:
    with pytest.raises(ArtifactError, match=r"nope\.safetensors: no such file"):
        read_artifact(tmp_path / "nope.safetensors")
    with pytest.raises(ArtifactError, match=r"not a regular file"):
        read_artifact(tmp_path)


@pytest.mark.parametrize(
    "content", [b"", b"garbage" * 20, b"\x10\x00\x00\x00\x00\x00\x00\x00{not json}}}}}"]
)
def test_a_file_that_is_not_safetensors_is_refused(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "bad.safetensors"
    path.write_bytes(content)
    with pytest.raises(ArtifactError, match=r"bad\.safetensors: not a safetensors file"):
        read_artifact(path)


def test_a_safetensors_file_without_our_metadata_is_refused(tmp_path: Path) -> None:
    meta = make_meta()
    for header, name in ((None, "none"), ({"format": "pt"}, "other")):
        path = raw_file(tmp_path / f"{name}.safetensors", random_tensors(meta), header)
        with pytest.raises(ArtifactError, match=rf"{name}\.safetensors: missing metadata"):
            read_artifact(path)


def test_an_unknown_format_version_is_refused(tmp_path: Path) -> None:
    meta = make_meta()
    header = {**meta.to_header(), VERSION_KEY: "2"}
    path = raw_file(tmp_path / "v2.safetensors", random_tensors(meta), header)
    with pytest.raises(ArtifactError, match=r"v2\.safetensors: unknown format version '2'"):
        read_artifact(path)


def _with_json(meta: ModelMetadata, **changes: object) -> dict[str, str]:
    data = json.loads(meta.to_header()[METADATA_KEY])
    for key, value in changes.items():
        if value is None:
            del data[key]
        else:
            data[key] = value
    return {VERSION_KEY: "1", METADATA_KEY: json.dumps(data)}


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"architecture": "transformer"}, r"unknown architecture 'transformer'"),
        (
            {"features": ["x_v_mps", "y_v", "x_a_mps2", "y_a_mps2", "stl_m"]},
            r"unknown model input\(s\) \['y_v'\]",
        ),
        ({"feature_std": [1, 1, 1, 1]}, r"feature_std has 4 values for 5 features"),
        ({"feature_mean": [0, 0, 0, 0, 0, 0]}, r"feature_mean has 6 values for 5 features"),
        ({"feature_std": [1, 1, 0, 1, 1]}, r"feature_std of y_a_mps2 must be finite and > 0"),
        ({"beta_std": -1}, r"beta_std must be a number"),
        ({"window_steps": None}, r"missing 1 required .*window_steps"),
        ({"surprise": 1}, r"unknown key\(s\) \['surprise'\]"),
    ],
)
def test_invalid_metadata_in_a_file_is_refused_naming_the_file(
    tmp_path: Path, changes: dict, match: str
) -> None:
    meta = make_meta()
    path = raw_file(
        tmp_path / "meta.safetensors", random_tensors(meta), _with_json(meta, **changes)
    )
    with pytest.raises(ArtifactError, match=rf"meta\.safetensors: .*{match}"):
        read_artifact(path)


def test_metadata_that_is_not_json_is_refused(tmp_path: Path) -> None:
    meta = make_meta()
    header = {VERSION_KEY: "1", METADATA_KEY: "{architecture: lstm"}
    path = raw_file(tmp_path / "j.safetensors", random_tensors(meta), header)
    with pytest.raises(ArtifactError, match=r"j\.safetensors: sideslip\.model is not valid JSON"):
        read_artifact(path)


def _mutate(tensors: dict[str, np.ndarray], how: str) -> dict[str, np.ndarray]:
    t = dict(tensors)
    if how == "missing":
        del t["lstm.bias_hh_l0"]
    elif how == "extra":
        t["lstm.weight_ih_l0_reverse"] = t["lstm.weight_ih_l0"].copy()
    elif how == "shape":
        t["lstm.weight_hh_l0"] = np.zeros((16, 5), np.float32)
    elif how == "dtype":
        t["head.bias"] = t["head.bias"].astype(np.float64)
    elif how == "int":
        t["head.bias"] = np.zeros(1, np.int32)
    elif how == "nan":
        w = t["lstm.weight_hh_l0"].copy()
        w[3, 2] = np.nan
        t["lstm.weight_hh_l0"] = w
    elif how == "inf":
        t["head.weight"] = np.full((1, 4), np.inf, np.float32)
    return t


@pytest.mark.parametrize(
    ("how", "match"),
    [
        ("missing", r"missing \['lstm\.bias_hh_l0'\], extra \[\]"),
        ("extra", r"missing \[\], extra \['lstm\.weight_ih_l0_reverse'\]"),
        ("shape", r"tensor lstm\.weight_hh_l0 has shape \(16, 5\), expected \(16, 4\)"),
        ("dtype", r"tensor head\.bias has dtype F64, expected F32"),
        ("int", r"tensor head\.bias has dtype I32, expected F32"),
        ("nan", r"tensor lstm\.weight_hh_l0 holds NaN or inf"),
        ("inf", r"tensor head\.weight holds NaN or inf"),
    ],
)
def test_tensors_that_do_not_match_the_metadata_are_refused(
    tmp_path: Path, how: str, match: str
) -> None:
    meta = make_meta()
    bad = _mutate(random_tensors(meta), how)
    path = raw_file(tmp_path / f"{how}.safetensors", bad, meta.to_header())
    with pytest.raises(ArtifactError, match=rf"{how}\.safetensors: .*{match}"):
        read_artifact(path)
    # The writer refuses the same tensors, before writing anything.
    out = tmp_path / "w" / "out.safetensors"
    with pytest.raises(ArtifactError, match=r"out\.safetensors: "):
        write_artifact(out, bad, meta)
    assert not out.exists()


def test_metadata_is_a_frozen_value() -> None:
    meta = make_meta()
    with pytest.raises(dataclasses.FrozenInstanceError):
        meta.hidden_units = 8  # type: ignore[misc]
    assert meta.directions == 1
    assert make_meta(architecture="bilstm").directions == 2


def test_a_per_sample_uncertainty_model_round_trips_and_is_checked(tmp_path: Path) -> None:
    from sideslip_msgs_py.uncertainty import Uncertainty

    unc = Uncertainty((1e-8, 2.5e-4, 8e-8, 1.5e-4), 1.09)
    meta = make_meta(uncertainty=unc.to_dict())
    path = write_artifact(tmp_path / "m.safetensors", random_tensors(meta), meta)
    assert Uncertainty.from_dict(read_artifact(path)[1].uncertainty) == unc
    assert make_meta().uncertainty is None  # older models: the validation RMSE²
    with pytest.raises(ArtifactError, match="uncertainty: scale"):
        make_meta(uncertainty={"coefficients": [1, 2, 3, 4], "scale": -1.0})
