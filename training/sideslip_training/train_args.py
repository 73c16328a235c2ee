"""The options of ``sideslip-train`` (:mod:`.cli` runs them): kept apart because its
``--help`` is the command's manual and is long."""

from __future__ import annotations

import argparse
from pathlib import Path

from sideslip_msgs_py.artifact import ARCHITECTURES
from sideslip_msgs_py.model_inputs import INPUT_SETS, PRIORS

from .config import PROFILES
from .inputs import add_car_argument
from .train_intervals import INTERVAL_POLICIES


def train_parser() -> argparse.ArgumentParser:
    """Every option of ``sideslip-train``, its help and the profiles' settings."""
    p = argparse.ArgumentParser(
        prog="sideslip-train",
        description=(
            "Train an LSTM or BiLSTM sideslip estimator on rosbag2 bags (ours or your "
            "car's, recorded with ros2 bag record or sideslip-record), optionally with "
            "PSO over learning rate and hidden units, and export it as one .safetensors "
            "file that the estimator node's pso_lstm back-end loads."
        ),
        epilog=(
            "Bags are split into training, validation (and, with --test-fraction, test) by "
            "bag, or for one long recording in time (--split; never by window); the z-score "
            "statistics come from the training part only. The run folder (default: OUT "
            "without suffix + '.run') holds config.json, history.json, metrics.json (with "
            "the test part's figures), the PSO history and state (pso_history.json, "
            "pso_state.json), plots and each particle's model; --resume continues an "
            "interrupted PSO from it. Profiles: "
            + "; ".join(
                f"{p.name}: {p.max_epochs} epochs, patience {p.patience}, batch "
                f"{p.batch_size}, stride {p.stride}, {p.default_hidden_units} units and "
                f"learning rate {p.default_learning_rate:g} without PSO, validation "
                f"{p.val_fraction:g}, PSO {p.pso.swarm_size} particles x "
                f"{p.pso.iterations} iterations"
                for p in PROFILES.values()
            )
            + " (each can be overridden by its option)."
        ),
    )
    p.add_argument(
        "--data", nargs="+", required=True, metavar="DIR", help="bags or folders of bags"
    )
    p.add_argument(
        "--val",
        nargs="+",
        metavar="DIR",
        help="validation bags (e.g. other cars than --data's, so that selection measures "
        "generalisation); default: a fraction of --data's bags",
    )
    p.add_argument(
        "--test",
        nargs="+",
        metavar="DIR",
        help="test bags, scored once after training (model and baselines, in metrics.json)",
    )
    p.add_argument(
        "--rehearse",
        nargs="+",
        metavar="DIR",
        help="more bags (the project's own topics; e.g. sideslip-generate runs of cars like "
        "--data's) for training only, never validation, test or the intervals: with "
        "--init, keeps what the start model knew beyond the recordings' range "
        "(docs/evaluation/fit-bags, 'Rehearsal')",
    )
    p.add_argument(
        "--split",
        choices=["auto", "bag", "time"],
        default="auto",
        help="how --data is split: by bag (whole bags to each side), or in time (the last "
        "fractions of every bag: for one long recording); auto: by bag from 3 bags on",
    )
    p.add_argument(
        "--val-fraction",
        type=float,
        help="share of --data for validation (default: the profile's, 0.2)",
    )
    p.add_argument(
        "--test-fraction",
        type=float,
        default=0.0,
        help="share of --data held out as test (in time: each bag's last part), scored "
        "once after training",
    )
    p.add_argument(
        "--refit",
        choices=["auto", "yes", "no"],
        default="auto",
        help="after early stopping chose the epoch count on validation, train again on "
        "training + validation for that many epochs and export that model; auto: when the "
        "split is in time (the validation part is then the stretch before the test)",
    )
    p.add_argument(
        "--epochs",
        type=int,
        metavar="N",
        help="train exactly N epochs, no early stopping and no choice (with --init, the "
        "start is not kept): e.g. the count a --folds run chose, given again for another "
        "start or seed; the validation split still scores the model, then it is refit on "
        "all the bags for N epochs (unless --refit no). Not with --folds or --pso",
    )
    p.add_argument(
        "--folds",
        type=int,
        default=1,
        metavar="K",
        help="choose the epoch count (and, with --init, whether to keep the start) by "
        "K-fold cross-validation over the training and validation bags (by bag; in time: "
        "K blocks of each run; a held-out fold is scored on its runs' mirror images too "
        "when the training mirrors) instead of on the validation split alone, then train on "
        "the training part for that count and refit on all (unless --refit no): K + 2 "
        "trainings, for a few minutes of data, where one validation split is a minute; "
        "the intervals are then calibrated on every bag, each scored by the fold network "
        "that did not train on it (default 1: the validation split; not with --pso)",
    )
    p.add_argument(
        "--intervals",
        choices=list(INTERVAL_POLICIES),
        default="auto",
        help="the per-sample σ the model publishes, calibrated on the validation runs "
        "with the model early stopping chose (before any refit), or with --folds on every "
        "bag out of fold: scale keeps the --init "
        "model's σ terms and fits their scale; fit fits terms and scale on halves of the "
        "validation bags; auto (default): scale when fine-tuning a model with σ terms, "
        "else fit with two or more validation bags, else none; no: none (the constant "
        "validation RMSE²)",
    )
    p.add_argument(
        "--window-s",
        type=float,
        help="window length in seconds (default 0.25, the paper's): the same horizon at "
        "every --rate-hz",
    )
    p.add_argument("--window-steps", type=int, help="window length in samples instead")
    p.add_argument(
        "--model",
        choices=list(ARCHITECTURES),
        help="architecture (required unless --init gives it)",
    )
    p.add_argument(
        "--init",
        metavar="MODEL",
        help="fine-tune: start from this model's weights (a .safetensors or a shipped name); "
        "its architecture, size, inputs, prior, window and rate are used, and options that "
        "contradict them are refused",
    )
    p.add_argument(
        "--normalization",
        choices=["keep", "refit"],
        default="keep",
        help="with --init: keep the model's z-score statistics (default; the first epoch "
        "starts from the model's answer) or refit them on the new data",
    )
    p.add_argument(
        "--interpolate",
        type=float,
        default=1.0,
        metavar="ALPHA",
        help="with --init: export the start model's weights moved this share of the way "
        "to the fine-tuned ones, θ0 + ALPHA (θ - θ0), before the σ calibration (default 1: "
        "the fine-tuned weights; sideslip-fit --bags uses 0.25 from fleet_ukf_merged and "
        "0.5 from fleet_ukf_ensemble and other starts, chosen on validation cars: "
        "docs/training.md); needs --normalization keep",
    )
    p.add_argument(
        "--init-members",
        choices=["keep", "join"],
        default="keep",
        help="with --init of a merged model (sideslip-merge): keep (default) trains each "
        "member on its own, the weights between members staying zero, so the result still "
        "streams member by member at the members' cost; join trains the wide network as "
        "one, its zeros fill in, and the estimator then runs it densely (docs/training.md, "
        '"Fine-tuning the five")',
    )
    p.add_argument("--pso", action="store_true", help="tune learning rate and hidden units by PSO")
    p.add_argument(
        "--features",
        choices=list(INPUT_SETS),
        help="model inputs (default: paper; with --init: the model's): paper (X_v, Y_v, "
        "X_a, Y_a, yaw rate, STL) and measurable (no Y_v) as measured; paper_kinematic "
        "(kinematic inputs only, no steering) and "
        "measurable_invariant (accelerations in g, road-wheel and understeer angles, the "
        "car's mass, wheelbase, weight split and CG height as inputs); measurable_observer "
        "(measurable_invariant plus the UKF observer's β̂ and road μ̂)",
    )
    p.add_argument(
        "--prior",
        choices=list(PRIORS),
        help="physics estimate the network corrects (β̂ = prior + network; default none, "
        "with --init the model's): none, "
        "kinematic_window (the window's dead-reckoned atan2(Y_v, X_v); needs Y_v), or ukf "
        "(the estimator's UKF with the car's nominal parameters; measurable channels)",
    )
    p.add_argument(
        "--observer-params",
        type=Path,
        metavar="UKF.yaml",
        help="the car's ukf params file (python -m sideslip_sim.ukf_params) for bags that "
        "record no car, when the inputs or the prior read the UKF observer",
    )
    p.add_argument(
        "--observer-value",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a setting of the UKF observer the model reads, as the estimator's ukf "
        "back-end names it (e.g. estimate_disturbance=true; repeatable; default: the "
        "back-end's defaults); stored in the model file so the node runs the same filter. "
        "Not with --init, whose network learnt its own filter",
    )
    p.add_argument(
        "--vehicle",
        type=Path,
        help="nominal parameters (YAML) of the car of bags that record none, for inputs "
        "that read the vehicle (simulated bags record theirs)",
    )
    add_car_argument(p)
    p.add_argument("--profile", default="quick", choices=list(PROFILES))
    p.add_argument(
        "--rate-hz",
        type=float,
        help="the rate the model runs at [Hz] (default: the bags' own, with --init the "
        "model's): bags at "
        "another rate are resampled to it (low-pass filtered first when downsampling), "
        "bags outside 50-1000 Hz refused; the report says which",
    )
    p.add_argument("--out", required=True, type=Path, metavar="FILE.safetensors")
    p.add_argument(
        "--topic-map",
        type=Path,
        metavar="FILE",
        help="read bags recorded with other topics/types through this map (YAML: topic and "
        "field of each channel and of the reference β or velocity; docs/topic-maps.md)",
    )
    p.add_argument("--force", action="store_true", help="replace --out and its run folder")
    p.add_argument("--run-dir", type=Path, help="run folder (default: OUT.run)")
    p.add_argument("--resume", action="store_true", help="continue the PSO in the run folder")
    p.add_argument("--device", default="auto", choices=["auto", "cpu", "cuda"])
    p.add_argument("--workers", type=int, default=1, help="parallel PSO particles (processes)")
    p.add_argument(
        "--ray-address", help="run PSO particles on this Ray cluster ('auto', ray://...)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--hidden-units", type=int, help="without --pso (default: the profile's)")
    p.add_argument("--learning-rate", type=float, help="without --pso (default: the profile's)")
    p.add_argument("--max-epochs", type=int, help="override the profile's epoch limit")
    p.add_argument("--stride", type=int, help="override the profile's window stride [samples]")
    p.add_argument("--patience", type=int, help="override the profile's early-stopping patience")
    p.add_argument(
        "--average-weights",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="score and keep a moving average of the weights over about the last epoch "
        "instead of the last step's (default on; docs/training.md, 'Small data')",
    )
    p.add_argument(
        "--mirror",
        choices=["auto", "yes", "no"],
        default="auto",
        help="also train on every training run mirrored left-right (steering, lateral "
        "velocity and acceleration, yaw rate and β negated): a car is symmetric, so this "
        "doubles the data; validation and test stay as recorded. auto (default): when the "
        "training part is small (under 1 M samples with the quick profile, as for the "
        "stride; docs/training.md, 'Small data')",
    )
    p.add_argument(
        "--mirror-val",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="also validate on every validation run mirrored left-right, so early "
        "stopping, the epoch kept, the validation figures and the intervals' calibration "
        "count both turning directions: for simulated drives that open every manoeuvre "
        "to the same side, as the fleet preset's do (default off: a recording is kept as "
        "driven; docs/evaluation/direction)",
    )
    p.add_argument("--batch-size", type=int, help="override the profile's batch size")
    p.add_argument("--swarm-size", type=int, help="override the profile's PSO swarm size")
    p.add_argument("--iterations", type=int, help="override the profile's PSO iterations")
    p.add_argument("--quiet", action="store_true")
    return p
