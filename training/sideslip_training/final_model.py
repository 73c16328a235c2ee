"""From the chosen training to the model that is exported: the optional refit on
training + validation for the epoch count early stopping chose, and the metadata the
artifact carries (inputs, statistics, metrics, provenance)."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import replace
from datetime import UTC, datetime
from typing import Any

from sideslip_msgs_py.artifact import ModelMetadata
from sideslip_msgs_py.data_source import (
    RECORDINGS_KEY,
    mirror_average_on,
    recordings_in,
    total_recordings,
)
from sideslip_msgs_py.fleet_envelope import FleetEnvelope

from . import __version__
from .train_plan import TrainPlan
from .trainer import EpochRecord, TrainResult, train_model
from .windows import WindowIndex


def wants_refit(
    refit: str,
    *,
    pso: bool,
    val_given: bool,
    split: str,
    folds: int = 1,
    fixed_epochs: bool = False,
) -> bool:
    """Whether to refit (--refit ``yes``/``no``/``auto``); never after PSO, whose model
    is the best particle's weights. ``auto`` refits a split in time without --val
    bags (the validation part is then the stretch before the test, too good to leave
    out), after cross-validation (``folds`` > 1), whose epoch count was chosen for
    training on (K − 1)/K of all the bags, not on the training part alone, and after
    ``--epochs`` (``fixed_epochs``): the validation split chose nothing, so holding it
    out of the final model buys nothing."""
    auto = folds > 1 or fixed_epochs or (not val_given and split == "time")
    return not pso and (refit == "yes" or (refit == "auto" and auto))


def refit(
    selection: TrainResult,
    plan: TrainPlan,
    log: Callable[[str], None],
    init_state: Mapping[str, Any] | None = None,
) -> tuple[TrainResult, list[EpochRecord]]:
    """Train again on training + validation for ``selection.best_epoch`` epochs (from
    ``init_state`` when fine-tuning), keeping the last epoch's weights.

    Returns the refit result carrying the selection's history and early stop (what
    chose the epoch count), and the refit's own epoch history.
    """
    data = plan.data
    both = WindowIndex.build(data.refit_runs, plan.spec, data.normalizer, plan.window, data.stride)
    log(f"refit on training + validation ({len(both.ends)} windows), {selection.best_epoch} epochs")
    result = train_model(
        replace(plan.base, max_epochs=selection.best_epoch),
        both,
        data.val,
        data.normalizer,
        init_state=init_state,
        keep_last=True,
    )
    result.stopped_early = selection.stopped_early
    result.history, refit_history = selection.history, result.history
    return result, refit_history


def recordings_learnt(plan: TrainPlan, *, kept_start: bool = False) -> int | None:
    """The recordings the exported model learnt from (``provenance["recordings"]``): the
    training data's and the start's; the start's alone when its weights were kept (the
    file is then the start model, and the node runs it as it ran the start)."""
    init = plan.init
    start = [recordings_in(init.meta.provenance)] if init is not None else []
    if kept_start:
        return total_recordings(start)
    return total_recordings([plan.data.recordings, *start])


def deployed_mirror(plan: TrainPlan) -> tuple[bool, bool]:
    """Whether the node's default (``pso_lstm.mirror_average: auto``) averages the start
    and the fine-tuned network with their mirror images; (False, False) when not
    fine-tuning (a training from scratch is selected on its network alone)."""
    if plan.init is None:
        return False, False
    after = recordings_learnt(plan)
    return (
        mirror_average_on("auto", plan.init.meta.provenance),
        mirror_average_on("auto", {} if after is None else {RECORDINGS_KEY: after}),
    )


def model_metadata(
    plan: TrainPlan,
    result: TrainResult,
    *,
    architecture: str,
    normalization: str,
    digest: str,
    metrics: dict[str, Any],
    pso_info: dict[str, Any] | None,
    command: str,
    wall_s: float,
) -> ModelMetadata:
    """The exported model's metadata: what the estimator needs to run it (inputs, window,
    step [s], statistics, prior, car, observer) and how it was made (``digest`` of the
    training data, metrics, PSO record, provenance with ``wall_s`` [s] so far)."""
    normalizer, init = plan.data.normalizer, plan.init
    spec, vehicle = plan.spec, plan.vehicle
    recordings = recordings_learnt(plan, kept_start=bool(metrics.get("kept_start_weights")))
    envelope = None
    if spec.needs_observer:
        from .observer import training_envelope

        # The cars of the training runs (a recording without a vehicle record: the
        # given params file's car); a fine-tuned model knows its init's cars as well.
        env = training_envelope(plan.data.train_runs, spec.observer_params_file, car=spec.car)
        if init is not None and init.meta.envelope is not None:
            env = env.union(FleetEnvelope.from_dict(init.meta.envelope))
        envelope = env.to_dict()
    return ModelMetadata(
        architecture=architecture,
        hidden_units=result.model.config.hidden_units,
        layers=result.model.config.layers,
        features=tuple(plan.features),
        window_steps=plan.window,
        dt_s=plan.dt_s,
        feature_mean=tuple(float(v) for v in normalizer.mean),
        feature_std=tuple(float(v) for v in normalizer.std),
        beta_mean=float(normalizer.beta_mean),
        beta_std=float(normalizer.beta_std),
        training_data_digest=digest,
        metrics=metrics,
        pso=pso_info,
        prior=spec.prior,
        vehicle=vehicle.to_dict() if vehicle is not None else None,
        observer=dict(spec.observer) if spec.observer is not None else None,
        envelope=envelope,
        created_utc=datetime.now(UTC).isoformat(timespec="seconds"),
        provenance={
            **(
                {
                    "init": init.path.name,
                    "init_data": init.meta.training_data_digest,
                    "normalization": normalization,
                    # Whether a merged start was trained member by member.
                    "init_members": "keep" if plan.base.keep_members else "join",
                }
                if init is not None
                else {}
            ),
            # Zero only when this model and its start learnt from simulated runs alone
            # (what the node's mirror_average auto goes by); absent when the start's
            # file does not say.
            **({} if recordings is None else {RECORDINGS_KEY: recordings}),
            "command": command,
            "profile": plan.profile.name,
            "device": result.device,
            "train_bags": len(plan.data.recorded_train_runs),
            "rehearsal_bags": len(plan.data.rehearsal_runs),
            "val_bags": len(plan.data.val_runs),
            "wall_s": round(wall_s, 1),
            "sideslip_training": __version__,
        },
    )
