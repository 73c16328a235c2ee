"""Node parameters as data: typed defaults, the node's and the core's parameters built from
them, ``--help``, and the shipped config YAMLs that must list exactly the declared
parameters with their defaults."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

import sideslip_sim.node as sim_node
from sideslip_estimator.backends import BACKENDS
from sideslip_estimator.estimator import EstimatorParams
from sideslip_estimator.imu_scale import ImuScaleParams
from sideslip_estimator.inputs import InputLimits
from sideslip_estimator.node_parameters import (
    PARAMETERS,
    NodeParams,
    estimator_params,
    help_page,
)
from sideslip_msgs_py.parameter_spec import ParameterSpec, help_text
from sideslip_sim.sensors import NOISE_PROFILES
from sideslip_sim.stream import select_runs
from sideslip_sim.vehicle import shipped_vehicles

ROOT = Path(__file__).resolve().parents[2]
ESTIMATOR_YAML = ROOT / "sideslip_estimator" / "config" / "estimator.yaml"
SIM_YAML = ROOT / "sideslip_sim" / "config" / "sim.yaml"


def _estimator_specs() -> dict[str, ParameterSpec]:
    specs = {p.name: p for p in PARAMETERS}
    for name, factory in BACKENDS.items():
        specs |= {f"{name}.{p.name}": p for p in factory.parameters}
    return specs


def _sim_specs() -> dict[str, ParameterSpec]:
    return {p.name: p for p in sim_node.PARAMETERS}


def _defaults() -> dict[str, object]:
    return {p.name: p.default for p in PARAMETERS}


# --- typed defaults ---------------------------------------------------------------------------

FLOAT_SUFFIXES = ("_s", "_m", "_mps", "_mps2", "_radps", "_radps2", "_hz", "_kmh", "_nm", "_pct")
FLOAT_NAMES = {
    "mu",
    "real_time_factor",
    "friction_initial",
    "friction_initial_sigma",
    "max_spread",
}
INT_NAMES = {
    "window_steps",
    "smoothing_steps",
    "seed",
    "randomized_count",
    "wait_for_subscribers",
    "threads",
    "memory_chunks",
}
BOOL_NAMES = {
    "publish_clock",
    "loop",
    "ground_truth",
    "tyre_relaxation",
    "estimate_friction",
    "estimate_disturbance",
}
STR_NAMES = {
    "backend",
    "params_file",
    "scenario",
    "vehicle",
    "noise",
    "model_file",
    "vehicle_file",
    "observer_params_file",
    "outside_fleet",
    "beyond_fit_range",
    "start_model_file",
    "engine",
    "frame_id",
    "frame",  # imu.frame of the sim: level / body
    "topic_map_file",
    "mode",  # imu_scale.mode: off / report / apply
    "state_file",
    "mirror_average",  # auto / true / false (it takes a bool as well: ParameterSpec.takes_bool)
}


def _expected_type(full_name: str) -> type:
    name = full_name.rsplit(".", 1)[-1]
    if name in INT_NAMES:
        return int
    if name in BOOL_NAMES:
        return bool
    if name in STR_NAMES:
        return str
    if name in FLOAT_NAMES or name.endswith(FLOAT_SUFFIXES):
        return float
    raise AssertionError(f"{full_name}: no type rule; add the name to this test")


@pytest.mark.parametrize(
    ("name", "spec"),
    [*_estimator_specs().items(), *(("sim:" + k, v) for k, v in _sim_specs().items())],
    ids=lambda x: x if isinstance(x, str) else "",
)
def test_every_parameter_default_has_the_type_its_name_implies(
    name: str, spec: ParameterSpec
) -> None:
    # A quantity with a unit must be a double: an int default would make rclpy refuse
    # `-p max_gap_s:=0.2`, and a float default for a count would refuse `:=100`.
    assert type(spec.default) is _expected_type(name.removeprefix("sim:"))
    assert spec.type_name in {"bool", "int", "double", "string"}
    assert spec.description.strip()


def test_help_lists_every_parameter_with_type_and_default() -> None:
    text = help_text("title", [("Parameters", PARAMETERS)])
    for p in PARAMETERS:
        assert f"{p.name} ({p.type_name}, default {p.default!r})" in text


# --- the core parameters from declared values -------------------------------------------------


def test_declared_defaults_build_the_core_defaults() -> None:
    params = estimator_params(_defaults())
    assert params == EstimatorParams()
    assert params.limits == InputLimits()


def test_declared_values_reach_the_core_parameters() -> None:
    values = _defaults() | {
        "window_steps": 50,
        "max_input_age_s": 0.02,
        "max_gap_s": 0.3,
        "min_speed_mps": 3.0,
        "limits.speed_mps": 70.0,
        "limits.acceleration_mps2": 30.0,
        "limits.yaw_rate_radps": 2.0,
        "limits.stl_m": 0.2,
    }
    params = estimator_params(values)
    assert params == EstimatorParams(
        window_steps=50,
        max_input_age_s=0.02,
        max_gap_s=0.3,
        min_speed_mps=3.0,
        limits=InputLimits(speed_mps=70.0, acceleration_mps2=30.0, yaw_rate_radps=2.0, stl_m=0.2),
    )


@pytest.mark.parametrize(
    ("name", "value"),
    [("window_steps", 0), ("window_steps", -5), ("max_input_age_s", 0.0),
     ("max_input_age_s", math.nan), ("max_gap_s", -0.1), ("max_gap_s", math.inf),
     ("min_speed_mps", -1.0), ("limits.speed_mps", 0.0), ("limits.acceleration_mps2", -1.0),
     ("limits.yaw_rate_radps", math.nan), ("limits.stl_m", math.inf)],
)  # fmt: skip
def test_bad_value_is_a_value_error_naming_the_parameter(name: str, value: object) -> None:
    with pytest.raises(ValueError, match=name.removeprefix("limits.")):
        estimator_params(_defaults() | {name: value})


# --- one home per default ---------------------------------------------------------------------


def _dataclass_defaults() -> dict[str, object]:
    """What each declared name configures, with the default its dataclass gives it."""
    node, core, limits = NodeParams(), EstimatorParams(), InputLimits()
    nested = ("core", "imu_scale")
    return {
        **{f.name: getattr(node, f.name) for f in dataclasses.fields(node) if f.name not in nested},
        **{
            f"imu_scale.{f.name}": getattr(node.imu_scale, f.name)
            for f in dataclasses.fields(node.imu_scale)
        },
        **{f.name: getattr(core, f.name) for f in dataclasses.fields(core) if f.name != "limits"},
        **{f"limits.{f.name}": getattr(limits, f.name) for f in dataclasses.fields(limits)},
    }


def test_every_dataclass_field_is_declared_and_nothing_else() -> None:
    # A new field of NodeParams, EstimatorParams or InputLimits must get a parameter.
    names = [p.name for p in PARAMETERS]
    assert len(names) == len(set(names)), "a parameter is declared twice"
    assert sorted(names) == sorted(_dataclass_defaults())


@pytest.mark.parametrize("spec", PARAMETERS, ids=lambda p: p.name)
def test_every_declared_default_is_the_default_of_the_dataclass_field_it_sets(
    spec: ParameterSpec,
) -> None:
    expected = _dataclass_defaults()[spec.name]
    assert spec.default == expected and type(spec.default) is type(expected)


# --- the node's parameters from declared values -----------------------------------------------


def test_declared_defaults_build_the_default_node_params() -> None:
    params = NodeParams.from_values(_defaults())
    assert params == NodeParams()
    assert params.core == EstimatorParams()


def test_declared_values_reach_the_node_params() -> None:
    values = _defaults() | {
        "backend": "kinematic",
        "topic_map_file": "my_car.yaml",
        "frame_id": "imu_link",
        "silence_timeout_s": 0.3,
        "status_rate_hz": 5.0,
        "velocity_sigma_mps": 0.5,
        "window_steps": 40,
        "input_rate_hz": 100.0,
        "limits.stl_m": 0.4,
        "imu_scale.mode": "apply",
        "imu_scale.state_file": "imu_scale.json",
        "imu_scale.max_spread": 0.002,
        "imu_scale.memory_chunks": 12,
    }
    params = NodeParams.from_values(values)
    assert params == NodeParams(
        backend="kinematic",
        topic_map_file="my_car.yaml",
        frame_id="imu_link",
        silence_timeout_s=0.3,
        status_rate_hz=5.0,
        velocity_sigma_mps=0.5,
        core=EstimatorParams(window_steps=40, input_rate_hz=100.0, limits=InputLimits(stl_m=0.4)),
        imu_scale=ImuScaleParams("apply", "imu_scale.json", 0.002, 12),
    )
    assert params.velocity_variance_m2ps2 == 0.25


@pytest.mark.parametrize(
    ("name", "value", "rule"),
    [("status_rate_hz", 0.0, "> 0"), ("status_rate_hz", -2.0, "> 0"),
     ("status_rate_hz", math.nan, "> 0"), ("status_rate_hz", math.inf, "> 0"),
     ("silence_timeout_s", 0.0, "> 0"), ("silence_timeout_s", -0.1, "> 0"),
     ("silence_timeout_s", math.nan, "> 0"), ("silence_timeout_s", math.inf, "> 0"),
     ("velocity_sigma_mps", -0.01, ">= 0"), ("velocity_sigma_mps", math.nan, ">= 0"),
     ("velocity_sigma_mps", math.inf, ">= 0"),
     ("input_rate_hz", -1.0, ">= 0"), ("input_rate_hz", math.nan, ">= 0"),
     ("min_speed_mps", math.nan, ">= 0"), ("window_steps", 0, ">= 1")],
)  # fmt: skip
def test_bad_node_value_is_a_value_error_naming_the_parameter_and_the_rule(
    name: str, value: object, rule: str
) -> None:
    with pytest.raises(ValueError) as info:
        NodeParams.from_values(_defaults() | {name: value})
    message = str(info.value)
    assert message.startswith(f"{name} must be") and rule in message
    assert message.endswith(repr(value)) or message.endswith(str(value))


def test_a_zero_velocity_sigma_is_allowed_and_gives_zero_variance() -> None:
    params = NodeParams.from_values(_defaults() | {"velocity_sigma_mps": 0.0})
    assert params.velocity_variance_m2ps2 == 0.0


@given(
    name=st.sampled_from(["status_rate_hz", "silence_timeout_s", "velocity_sigma_mps"]),
    value=st.floats(allow_nan=True, allow_infinity=True),
)
def test_a_node_value_is_refused_exactly_when_it_is_outside_its_range(
    name: str, value: float
) -> None:
    # A rate and a timeout must be > 0 (a 0 Hz timer never fires, a 0 s timeout always
    # warns); a σ may be 0 (an exact speed), never negative; none may be NaN or infinite.
    valid = math.isfinite(value) and (value >= 0.0 if name == "velocity_sigma_mps" else value > 0)
    if valid:
        assert getattr(NodeParams(**{name: value}), name) == value
    else:
        with pytest.raises(ValueError, match=f"^{name} must be finite"):
            NodeParams(**{name: value})


def test_node_params_are_frozen() -> None:
    with pytest.raises(dataclasses.FrozenInstanceError):
        NodeParams().status_rate_hz = 10.0  # type: ignore[misc]


# --- --help ------------------------------------------------------------------------------------


def test_help_page_lists_the_node_parameters_then_each_backend_under_its_prefix() -> None:
    text = help_page()
    backend_headings = [f"Back-end {name} (parameters {name}.*):" for name in BACKENDS]
    starts = [text.index("Parameters:"), *(text.index(h) for h in backend_headings)]
    assert starts == sorted(starts), "the node's parameters first, back-ends in registry order"
    sections = [text[a:b] for a, b in zip(starts, [*starts[1:], len(text)], strict=True)]
    for p in PARAMETERS:
        assert f"  {p.name} ({p.type_name}, default {p.default!r})" in sections[0]
    for section, factory in zip(sections[1:], BACKENDS.values(), strict=True):
        for p in factory.parameters:
            assert f"  {p.name} ({p.type_name}, default {p.default!r})" in section
    assert text.startswith("sideslip-estimator (ros2 run sideslip_estimator estimator_node)")


def test_backend_parameter_describes_every_registered_backend() -> None:
    backend = next(p for p in PARAMETERS if p.name == "backend")
    for name in BACKENDS:
        assert name in backend.description
    assert backend.default in BACKENDS


def test_sim_parameter_defaults_are_valid_choices() -> None:
    specs = _sim_specs()
    assert specs["noise"].default in NOISE_PROFILES
    assert specs["vehicle"].default in shipped_vehicles()
    assert select_runs(str(specs["scenario"].default))


# --- config YAMLs -------------------------------------------------------------------------------


def _yaml_parameters(path: Path) -> dict[str, object]:
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert list(data) == ["/**"], f"{path}: expected one '/**' section"
    assert list(data["/**"]) == ["ros__parameters"]
    return data["/**"]["ros__parameters"]


@pytest.mark.parametrize(
    ("path", "specs"),
    [(ESTIMATOR_YAML, _estimator_specs()), (SIM_YAML, _sim_specs())],
    ids=["estimator.yaml", "sim.yaml"],
)
def test_config_yaml_lists_exactly_the_declared_parameters_with_their_defaults(
    path: Path, specs: dict[str, ParameterSpec]
) -> None:
    listed = _yaml_parameters(path)
    assert sorted(listed) == sorted(specs), f"{path.name} and the declarations differ"
    for name, spec in specs.items():
        value = listed[name]
        # rclpy refuses a value of another type than the declared one (no int for double).
        assert type(value) is type(spec.default), f"{path.name}: {name} = {value!r}"
        if isinstance(value, float):
            # Written with 10 significant digits (1/3.6, radians(0.2)).
            assert math.isclose(value, spec.default, rel_tol=1e-9), f"{path.name}: {name}"
        else:
            assert value == spec.default, f"{path.name}: {name}"


def test_estimator_yaml_lists_backend_parameters_under_the_backend_prefix() -> None:
    listed = _yaml_parameters(ESTIMATOR_YAML)
    for name, factory in BACKENDS.items():
        assert {k for k in listed if k.startswith(f"{name}.")} == {
            f"{name}.{p.name}" for p in factory.parameters
        }
