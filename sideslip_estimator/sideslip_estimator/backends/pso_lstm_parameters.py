"""The ``pso_lstm`` back-end's node parameters (``pso_lstm.*``), with what each one
chooses; the behaviour behind them is described in :mod:`.pso_lstm`."""

from __future__ import annotations

from typing import Final

from sideslip_msgs_py.parameter_spec import ParameterSpec

PSO_LSTM_PARAMETERS: Final = (
    ParameterSpec(
        "model_file",
        "",
        "Model artifact (.safetensors written by sideslip-train), or the name of a "
        "shipped model (sideslip_estimator/data/models/NAME.safetensors); empty = the "
        "shipped default: fleet_ukf_paper when observer_params_file is set (kinematics "
        "plus the UKF with the car's parameters), else fleet_lstm_paper (kinematics "
        "only, no car parameters).",
    ),
    ParameterSpec(
        "vehicle_file",
        "",
        "Nominal parameters (YAML) of the car, for a model that reads them (its "
        "vehicle.* inputs, road-wheel angle, ...): mass_kg, wheelbase_m, "
        "cg_to_front_axle_m, cg_height_m, track_m, stl_per_road_wheel_angle_m_per_rad, "
        "tire_rolling_radius_m; or a simulator vehicle file. Empty = the car stored in "
        "the model, if any.",
    ),
    ParameterSpec(
        "observer_params_file",
        "",
        "The car's ukf params file (a shipped name or a YAML path written by `python -m "
        "sideslip_sim.ukf_params VEHICLE`), for a model that reads the UKF observer "
        "(ukf.* inputs or the ukf prior); unused otherwise.",
    ),
    ParameterSpec(
        "outside_fleet",
        "auto",
        "For a model that reads the UKF and records its training cars' range: what to "
        "do when the car (observer_params_file) lies outside it. prior: publish the "
        "UKF's own estimate (the network's correction was learnt on other cars); "
        "network: publish the model's estimate; refuse: do not start; auto: prior for "
        "a residual on the UKF, network otherwise. Both publishing choices make the "
        "node's status WARN.",
    ),
    ParameterSpec(
        "beyond_fit_range",
        "auto",
        "For a model fine-tuned on one car's recordings (sideslip-fit --bags; its σ "
        "records their range): what to publish while the input window reaches beyond "
        "that range. start: the estimate and σ of the model it started from "
        "(start_model_file), run beside it on every sample; model: this model's, σ "
        "widened; auto: start when the recordings stayed under 5 m/s² of lateral "
        "acceleration (gentle driving, where fine-tuning forgets the limit) and that "
        "model is found, else model.",
    ),
    ParameterSpec(
        "start_model_file",
        "",
        "The model a fine-tuned model_file started from (a path or a shipped name), for "
        "beyond_fit_range; empty = the shipped model the file names as its start, if it "
        "is shipped with the same training data.",
    ),
    ParameterSpec(
        "engine",
        "numba",
        "numba: the streaming engine (all in-flight windows advance by one batched LSTM "
        "step per sample; no torch needed) as one compiled float32 call per layer "
        "(numpy when numba is not installed); numpy: the same in float64 numpy calls "
        "(the exact reference, 2-3x slower); torch: the whole window per sample "
        "through torch (the per-window path, bit for bit the trainer's network). A "
        "stacked BiLSTM always takes torch.",
    ),
    ParameterSpec(
        "mirror_average",
        "auto",
        "Average the network with its own mirror image (the inputs of the same drive "
        "turned the other way, the output negated back): the estimate of a right turn "
        "is then exactly that of the mirrored left turn. true, false, or auto: on for a "
        "model that records it learnt from simulated runs only (every shipped model; "
        "a car is symmetric, the fleet's drives were not), off for one that learnt from "
        "recordings (their sensor offsets and the car's own asymmetry would be "
        "cancelled) or whose file does not say. On the held-out cars it lowered every "
        "fleet model's MAE (docs/evaluation/direction). Costs a second network pass per "
        "sample.",
        takes_bool=True,
    ),
    ParameterSpec(
        "threads",
        1,
        "CPU threads of the torch engine (torch.set_num_threads: process-wide). One is "
        "fastest for a single 100-step window. The numpy engine uses numpy's BLAS "
        "(OPENBLAS_NUM_THREADS).",
    ),
)
