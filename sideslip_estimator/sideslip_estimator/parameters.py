"""The estimator node's parameters (declared by the node, listed by ``--help``)."""

from __future__ import annotations

from collections.abc import Mapping

from sideslip_msgs_py.parameters import ParameterSpec
from sideslip_msgs_py.timing import WINDOW_STEPS

from .estimator import EstimatorParams
from .inputs import InputLimits

PARAMETERS = (
    ParameterSpec(
        "backend",
        "pso_lstm",
        "Estimator back-end: pso_lstm (a trained network, pso_lstm.model_file; by default "
        "the shipped fleet model), kinematic (atan2(Y_v, X_v)), single_track "
        "(bicycle-model Kalman filter) or ukf (unscented Kalman filter, Magic Formula tyres).",
    ),
    ParameterSpec("window_steps", WINDOW_STEPS, "Sliding-window length in samples (100 = 250 ms)."),
    ParameterSpec(
        "topic_map_file",
        "",
        "Inputs from another stack's topics: a topic map YAML (docs/topic-maps.md) with the "
        'message type of each entry; "" = the contract topics /vehicle/imu, twist, steering.',
    ),
    ParameterSpec(
        "max_input_age_s",
        0.05,
        "A sample is rejected when its twist or steering stamp differs from the IMU stamp "
        "by more than this [s].",
    ),
    ParameterSpec(
        "max_gap_s",
        0.1,
        "A gap between accepted samples longer than this [s] restarts the window.",
    ),
    ParameterSpec(
        "min_speed_mps", 1.0, "No estimate below this X_v [m/s] (β is undefined at rest)."
    ),
    ParameterSpec(
        "input_rate_hz",
        0.0,
        "Expected IMU rate [Hz]: steps missing at this rate are counted as dropped, and a "
        "measured rate more than 10 % off turns the status to WARN. 0 = the model's rate "
        "(pso_lstm: its file's; 400 for the filters). Whatever this says, a pso_lstm model "
        "fed another rate than its own publishes nothing (status ERROR naming both).",
    ),
    ParameterSpec(
        "frame_id",
        "base_link",
        "Frame the IMU and twist must be expressed in; another frame is used as is and "
        'reported (WARN). "" = no check.',
    ),
    ParameterSpec(
        "silence_timeout_s",
        0.1,
        "An input topic silent for longer than this [s] turns the status to WARN.",
    ),
    ParameterSpec("status_rate_hz", 2.0, "Rate of /sideslip/status [Hz]."),
    ParameterSpec(
        "velocity_sigma_mps",
        1.0 / 3.6,
        "1-σ of X_v [m/s] used for the v_x variance in /sideslip/twist.",
    ),
    ParameterSpec("limits.speed_mps", 100.0, "|X_v|, |Y_v| beyond this [m/s] are rejected."),
    ParameterSpec(
        "limits.acceleration_mps2", 50.0, "|X_a|, |Y_a| beyond this [m/s²] are rejected."
    ),
    ParameterSpec("limits.yaw_rate_radps", 5.0, "|yaw rate| beyond this [rad/s] is rejected."),
    ParameterSpec("limits.stl_m", 1.5, "|steering rack travel| beyond this [m] is rejected."),
)


def estimator_params(values: Mapping[str, object]) -> EstimatorParams:
    """Core parameters from declared values (raises ValueError naming the bad one)."""
    limits = InputLimits(
        **{k.split(".", 1)[1]: float(v) for k, v in values.items() if k.startswith("limits.")}  # type: ignore[arg-type]
    )
    return EstimatorParams(
        window_steps=int(values["window_steps"]),  # type: ignore[call-overload]
        max_input_age_s=float(values["max_input_age_s"]),  # type: ignore[arg-type]
        max_gap_s=float(values["max_gap_s"]),  # type: ignore[arg-type]
        min_speed_mps=float(values["min_speed_mps"]),  # type: ignore[arg-type]
        input_rate_hz=float(values["input_rate_hz"]),  # type: ignore[arg-type]
        limits=limits,
    )
