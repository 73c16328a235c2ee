"""The estimator node's parameters: the table it declares (``--help`` lists it, with each
back-end's), and the typed, checked :class:`NodeParams` built from the declared values.

Each default has one home: the core's rules in :class:`~.estimator.EstimatorParams` and
:class:`~.inputs.InputLimits`, the node's own settings in :class:`NodeParams`. The table
takes its defaults from those dataclasses and adds only names and descriptions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

from sideslip_msgs_py.parameter_spec import ParameterSpec, help_text

from .backends import BACKENDS
from .estimator import EstimatorParams
from .imu_scale import ImuScaleParams
from .inputs import InputLimits


@dataclass(frozen=True)
class NodeParams:
    """The estimator node's parameters, typed and checked (units in the names)."""

    backend: str = "pso_lstm"
    topic_map_file: str = ""
    """A topic map YAML for another stack's topics; "" = the contract topics."""
    frame_id: str = "base_link"
    """Frame the IMU and twist must be expressed in ("" = no check)."""
    silence_timeout_s: float = 0.1
    status_rate_hz: float = 2.0
    velocity_sigma_mps: float = 1.0 / 3.6
    """1-σ of X_v for the v_x variance in /sideslip/twist."""
    core: EstimatorParams = field(default_factory=EstimatorParams)
    """The rules of the estimator core (window, input checks, limits)."""
    imu_scale: ImuScaleParams = field(default_factory=ImuScaleParams)
    """The check (and correction) of Y_a's scale while driving."""

    def __post_init__(self) -> None:
        for name in ("status_rate_hz", "silence_timeout_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"{name} must be finite and > 0, got {value}")
        sigma = self.velocity_sigma_mps
        if not (math.isfinite(sigma) and sigma >= 0.0):
            raise ValueError(f"velocity_sigma_mps must be finite and >= 0, got {sigma}")

    @property
    def velocity_variance_m2ps2(self) -> float:
        """Variance of X_v [m²/s²] published in /sideslip/twist."""
        return self.velocity_sigma_mps**2

    @classmethod
    def from_values(cls, values: Mapping[str, Any]) -> NodeParams:
        """From declared values, named as in :data:`PARAMETERS` (raises ValueError naming
        the bad one)."""
        core = estimator_params(values)
        return cls(
            backend=str(values["backend"]),
            topic_map_file=str(values["topic_map_file"]),
            frame_id=str(values["frame_id"]),
            silence_timeout_s=float(values["silence_timeout_s"]),
            status_rate_hz=float(values["status_rate_hz"]),
            velocity_sigma_mps=float(values["velocity_sigma_mps"]),
            core=core,
            imu_scale=ImuScaleParams(
                mode=str(values["imu_scale.mode"]),
                state_file=str(values["imu_scale.state_file"]),
                max_spread=float(values["imu_scale.max_spread"]),
                memory_chunks=int(values["imu_scale.memory_chunks"]),
            ),
        )


def estimator_params(values: Mapping[str, Any]) -> EstimatorParams:
    """Core parameters from declared values (raises ValueError naming the bad one)."""
    limits = InputLimits(
        **{k.split(".", 1)[1]: float(v) for k, v in values.items() if k.startswith("limits.")}
    )
    return EstimatorParams(
        window_steps=int(values["window_steps"]),
        max_input_age_s=float(values["max_input_age_s"]),
        max_gap_s=float(values["max_gap_s"]),
        min_speed_mps=float(values["min_speed_mps"]),
        input_rate_hz=float(values["input_rate_hz"]),
        limits=limits,
    )


def _defaults() -> dict[str, bool | int | float | str]:
    """Every declared parameter's default, read from the dataclasses that own it."""
    node, core = NodeParams(), EstimatorParams()
    nested = ("core", "imu_scale")
    return {
        **{f.name: getattr(node, f.name) for f in fields(NodeParams) if f.name not in nested},
        **{f"imu_scale.{f.name}": getattr(node.imu_scale, f.name) for f in fields(ImuScaleParams)},
        **{f.name: getattr(core, f.name) for f in fields(EstimatorParams) if f.name != "limits"},
        **{f"limits.{f.name}": getattr(core.limits, f.name) for f in fields(InputLimits)},
    }


_DEFAULTS = _defaults()


def _spec(name: str, description: str) -> ParameterSpec:
    return ParameterSpec(name, _DEFAULTS[name], description)


PARAMETERS = (
    _spec(
        "backend",
        "Estimator back-end: pso_lstm (a trained network, pso_lstm.model_file; by default "
        "the shipped fleet model), kinematic (atan2(Y_v, X_v)), single_track "
        "(bicycle-model Kalman filter) or ukf (unscented Kalman filter, Magic Formula tyres).",
    ),
    _spec("window_steps", "Sliding-window length in samples (100 = 250 ms)."),
    _spec(
        "topic_map_file",
        "Inputs from another stack's topics: a topic map YAML (docs/topic-maps.md) with the "
        'message type of each entry; "" = the contract topics /vehicle/imu, twist, steering.',
    ),
    _spec(
        "max_input_age_s",
        "A sample is rejected when its twist or steering stamp differs from the IMU stamp "
        "by more than this [s].",
    ),
    _spec("max_gap_s", "A gap between accepted samples longer than this [s] restarts the window."),
    _spec("min_speed_mps", "No estimate below this X_v [m/s] (β is undefined at rest)."),
    _spec(
        "input_rate_hz",
        "Expected IMU rate [Hz]: steps missing at this rate are counted as dropped, and a "
        "measured rate more than 10 % off turns the status to WARN. 0 = the model's rate "
        "(pso_lstm: its file's; 400 for the filters). Whatever this says, a pso_lstm model "
        "fed another rate than its own publishes nothing (status ERROR naming both).",
    ),
    _spec(
        "frame_id",
        "Frame the IMU and twist must be expressed in; another frame is used as is and "
        'reported (WARN). "" = no check.',
    ),
    _spec(
        "silence_timeout_s",
        "An input topic silent for longer than this [s] turns the status to WARN.",
    ),
    _spec("status_rate_hz", "Rate of /sideslip/status [Hz]."),
    _spec("velocity_sigma_mps", "1-σ of X_v [m/s] used for the v_x variance in /sideslip/twist."),
    _spec(
        "imu_scale.mode",
        "Y_a checked against speed and yaw rate while driving (a body-frame IMU without "
        "attitude reads 9-15 % of gravity into it): off; report (status values, WARN beyond "
        "±3 %); apply (also correct Y_a by the measured scale and bias once confident).",
    ),
    _spec(
        "imu_scale.state_file",
        'File that keeps the Y_a measurement across restarts (JSON; "" = not kept).',
    ),
    _spec(
        "imu_scale.max_spread",
        "The measured scale is applied once its 1-σ (jackknife over chunks of about a "
        "minute) is below this [-].",
    ),
    _spec("imu_scale.memory_chunks", "Chunks of driving (about a minute each) remembered."),
    _spec("limits.speed_mps", "|X_v|, |Y_v| beyond this [m/s] are rejected."),
    _spec("limits.acceleration_mps2", "|X_a|, |Y_a| beyond this [m/s²] are rejected."),
    _spec("limits.yaw_rate_radps", "|yaw rate| beyond this [rad/s] is rejected."),
    _spec("limits.stl_m", "|steering rack travel| beyond this [m] is rejected."),
)


def help_page() -> str:
    """The node's ``--help``: its parameters, then each back-end's under its prefix."""
    groups = [("Parameters", PARAMETERS)] + [
        (f"Back-end {name} (parameters {name}.*)", f.parameters) for name, f in BACKENDS.items()
    ]
    return help_text(
        "sideslip-estimator (ros2 run sideslip_estimator estimator_node): sideslip "
        "angle from the vehicle sensor topics, on /sideslip.",
        groups,
    )
