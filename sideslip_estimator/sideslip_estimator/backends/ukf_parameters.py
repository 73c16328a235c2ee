"""The ``ukf`` back-end's parameters: the node's parameter table and the noise settings
tuned on training data (``python -m sideslip_training.ukf_tuning``)."""

from __future__ import annotations

from typing import Final

from sideslip_msgs_py.parameter_spec import ParameterSpec

TUNED_PARAMETERS: Final = (
    "yaw_rate_sigma_radps",
    "lateral_acceleration_sigma_mps2",
    "longitudinal_velocity_sigma_mps",
    "process_sigma_longitudinal_mps2",
    "process_sigma_lateral_mps2",
    "process_sigma_yaw_radps2",
    "process_sigma_slip_rad_per_sqrt_s",
    "process_sigma_friction_per_sqrt_s",
)
"""The parameters tuned on training data (``python -m sideslip_training.ukf_tuning``,
PSO over their log10). The defaults (since 2026-12-03): one round, 10 particles × 6
swarms, on 47 fleet training bags of 12 cars (``sideslip-generate --preset fleet --count
48 --seed 1``, the one spun run left out, paper noise), each bag with its own car's
effective-axle params (``--params-file recorded``), centred on the earlier defaults
(tuned on ``paper_sedan`` bags with tyre-only axles); training β RMSE 0.141° → 0.055°.
Chosen on validation bags (docs/training.md, "The UKF's noise on the fleet")."""

UKF_PARAMETERS: Final = (
    ParameterSpec(
        "params_file",
        "paper_sedan",
        "UKF vehicle parameters: a shipped name (paper_sedan, compact_rwd) or a YAML "
        "path written by `python -m sideslip_sim.ukf_params VEHICLE`.",
    ),
    ParameterSpec(
        "yaw_rate_sigma_radps",
        0.002722,
        "Measurement 1-σ of the yaw rate [rad/s] (tuned; the paper's sensor: 0.0035).",
    ),
    ParameterSpec(
        "lateral_acceleration_sigma_mps2",
        0.3463,
        "Measurement 1-σ of a_y [m/s²]: sensor noise plus the model's error (tuned).",
    ),
    ParameterSpec(
        "longitudinal_velocity_sigma_mps",
        0.9826,
        "Measurement 1-σ of X_v [m/s] (tuned; the paper's sensor: 0.28).",
    ),
    ParameterSpec(
        "process_sigma_longitudinal_mps2",
        0.2585,
        "Process noise on v̇_x [m/s² per √Hz]: X_a noise and bias (tuned).",
    ),
    ParameterSpec(
        "process_sigma_lateral_mps2",
        0.01594,
        "Process noise on v̇_y [m/s² per √Hz]: how far the tyres may leave the model (tuned).",
    ),
    ParameterSpec(
        "process_sigma_yaw_radps2",
        0.3837,
        "Process noise on ψ̈ [rad/s² per √Hz] (tuned).",
    ),
    ParameterSpec(
        "tyre_relaxation",
        True,
        "Model the tyres' lag: relaxed slip angles as states, relaxation lengths from "
        "params_file (else the forces follow the kinematic slip at once).",
    ),
    ParameterSpec(
        "process_sigma_slip_rad_per_sqrt_s",
        0.05733,
        "Process noise on the relaxed slip angles [rad/√s] (with tyre_relaxation; tuned).",
    ),
    ParameterSpec(
        "estimate_friction",
        True,
        "Estimate road μ as a random-walk state (else μ stays at friction_initial).",
    ),
    ParameterSpec(
        "friction_initial",
        1.0,
        "Road μ relative to the tyre's test surface at (re)start [-].",
    ),
    ParameterSpec(
        "friction_initial_sigma",
        0.3,
        "1-σ of friction_initial [-] (with estimate_friction).",
    ),
    ParameterSpec(
        "process_sigma_friction_per_sqrt_s",
        0.1583,
        "Random walk of road μ [1/√s] (with estimate_friction; tuned).",
    ),
    ParameterSpec(
        "friction_memory_s",
        20.0,
        "Time constant [s] of μ's return to friction_initial (with estimate_friction): "
        "in the tyres' linear range nothing observes μ, and this bounds its 1-σ at "
        "process_sigma_friction_per_sqrt_s·√(memory/2) instead of letting it grow.",
    ),
    ParameterSpec(
        "estimate_disturbance",
        False,
        "Estimate a lateral acceleration that the tyre model does not explain (gravity's "
        "share on a banked road, the model's own force error) as a state: it drives v̇_y "
        "and is in the measured a_y, not in the tyres' forces (off by default: "
        "docs/evaluation/road-bank says where it helps and where it costs).",
    ),
    ParameterSpec(
        "disturbance_sigma_mps2",
        1.0,
        "Stationary 1-σ of the lateral disturbance [m/s²] (with estimate_disturbance), "
        "also its 1-σ at (re)start (chosen on validation cars, docs/evaluation/road-bank).",
    ),
    ParameterSpec(
        "disturbance_memory_s",
        3.0,
        "Time constant [s] of the disturbance's return to 0 (with estimate_disturbance; "
        "chosen on validation cars).",
    ),
    ParameterSpec(
        "min_speed_mps",
        3.0,
        "Below this X_v [m/s] slip angles are ill-defined: the filter restarts, no estimate.",
    ),
)
"""Name, default and description of each parameter (``ukf.NAME`` on the node)."""
