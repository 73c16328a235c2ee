"""What one ``sideslip-train`` call will do, resolved from its options before anything is
written: the profile with its overrides, the model to train (new, or fine-tuned from
``--init``), its TrainConfig and inputs, the checked outputs and the loaded data; and
the record of it all that the run folder keeps (config.json).

Every refusal happens here, before the run folder is made: a refused call leaves
nothing behind.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import yaml

from sideslip_msgs_py.model_inputs import input_set
from sideslip_msgs_py.vehicle_description import VehicleDescription

from . import __version__
from .cli_errors import CliError
from .config import TrainProfile, profile
from .dataset import data_digest
from .init_model import InitModel, check_fit, load_init
from .inputs import InputSpec
from .run_folder import check_out
from .search import particle_threads
from .trainer import TrainConfig, pick_device
from .training_data import (
    DataChoice,
    TrainingData,
    load_training_data,
    recorded_rate_hz,
    sample_period_s,
    window_steps,
)
from .weight_interpolation import check_alpha


@dataclass(frozen=True)
class TrainPlan:
    """A training ready to start: ``window`` in samples, ``dt_s`` the bags' common
    sample period [s] (the model's step), ``init`` the model a fine-tuning starts from."""

    profile: TrainProfile
    base: TrainConfig
    init: InitModel | None
    features: tuple[str, ...]
    vehicle: VehicleDescription | None
    spec: InputSpec
    window: int
    run_dir: Path
    data: TrainingData
    dt_s: float

    def init_state(self) -> Mapping[str, Any] | None:
        """The weights a training starts from: ``init``'s, or None (a seeded start)."""
        return self.init.net.state_dict() if self.init is not None else None


def profile_from_args(args: argparse.Namespace) -> TrainProfile:
    """--profile with the options that override it; the split fractions checked."""
    prof = profile(args.profile)
    for name in ("max_epochs", "stride", "patience", "batch_size"):
        value = getattr(args, name)
        if value is not None:
            if value < 1:
                flag = name.replace("_", "-")
                raise CliError(f"{name} must be >= 1 (--{flag}), got {value}")
            prof = replace(prof, **{name: value})
    for name in ("swarm_size", "iterations"):
        value = getattr(args, name)
        if value is not None:
            if value < 1:
                raise CliError(f"--{name.replace('_', '-')} must be >= 1, got {value}")
            prof = replace(prof, pso=replace(prof.pso, **{name: value}))
    for name in ("val_fraction", "test_fraction"):
        value = getattr(args, name)
        if value is not None and not 0.0 <= value < 1.0:
            raise CliError(f"--{name.replace('_', '-')} must be in [0, 1), got {value}")
    if (args.val_fraction or 0.0) + args.test_fraction >= 1.0:
        raise CliError("--val-fraction + --test-fraction must leave data to train on")
    return prof


def resolve_model(
    args: argparse.Namespace,
    prof: TrainProfile,
    init: InitModel | None,
    log: Callable[[str], None],
) -> tuple[tuple[str, ...], int, int]:
    """The model's inputs, hidden units and layers: from the options and the profile,
    or from ``init``'s metadata (options that contradict it are refused).

    Fills ``args.model``, ``prior`` and ``rate_hz`` [Hz] (with ``init`` also the window)
    in place, so that config.json records the values the run used.
    """
    if init is None:
        if args.model is None:
            raise CliError("--model is required (or --init MODEL to fine-tune one)")
        features = input_set(args.features or "paper")
        args.prior = args.prior or "none"
        if args.rate_hz is None:
            args.rate_hz = recorded_rate_hz(args.data, args.topic_map)
            log(f"model rate {args.rate_hz:g} Hz: the bags' own (--rate-hz to choose)")
        hidden_units = prof.default_hidden_units if args.hidden_units is None else args.hidden_units
        return features, hidden_units, prof.layers
    m = init.meta
    given_window = (
        window_steps(m.dt_s, steps=args.window_steps, seconds=args.window_s)
        if args.window_s is not None or args.window_steps is not None
        else None
    )
    check_fit(
        init,
        architecture=args.model,
        features=args.features,
        prior=args.prior,
        hidden_units=args.hidden_units,
        rate_hz=args.rate_hz,
        window_steps=given_window,
        pso=args.pso,
    )
    args.model, args.prior, args.rate_hz = m.architecture, m.prior, 1.0 / m.dt_s
    args.window_steps, args.window_s = m.window_steps, None
    return tuple(m.features), m.hidden_units, m.layers


def observer_values(items: Sequence[str]) -> dict[str, Any]:
    """``KEY=VALUE`` settings of the UKF observer (``--observer-value``), each value read
    as YAML (true, 1.5, ...); names and types are checked against the back-end when the
    input spec is built."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise CliError(f"--observer-value must be KEY=VALUE, got {item!r}")
        try:
            out[key.strip()] = yaml.safe_load(text)
        except yaml.YAMLError:
            raise CliError(f"--observer-value {item!r}: the value is not YAML") from None
    return out


def plan_training(args: argparse.Namespace, log: Callable[[str], None]) -> TrainPlan:
    """Resolve the options, check the outputs and load the data (nothing is written).

    Raises CliError, DatasetError, FeatureError, InitError, ImportError (no Ray for
    --ray-address) or another ValueError for input a user can fix.
    """
    prof = profile_from_args(args)
    init = load_init(args.init) if args.init else None
    features, hidden_units, layers = resolve_model(args, prof, init, log)
    vehicle = VehicleDescription.load(args.vehicle) if args.vehicle else None
    if vehicle is None and init is not None and init.meta.vehicle is not None:
        vehicle = VehicleDescription.from_mapping(init.meta.vehicle)
    if args.workers < 1:
        raise CliError(f"--workers must be >= 1, got {args.workers}")
    base = TrainConfig(
        architecture=args.model,
        hidden_units=hidden_units,
        layers=layers,
        learning_rate=(
            prof.default_learning_rate if args.learning_rate is None else args.learning_rate
        ),
        max_epochs=prof.max_epochs,
        patience=prof.patience,
        batch_size=prof.batch_size,
        seed=args.seed,
        device=str(pick_device(args.device)),
        average_weights=args.average_weights,
        keep_members=args.init_members == "keep",
    )
    if args.ray_address:
        from .parallel import import_ray

        import_ray()
    run_dir = check_out(args.out, run_dir=args.run_dir, force=args.force, resume=args.resume)
    observer_file = str(args.observer_params) if args.observer_params else None
    if not (math.isfinite(args.rate_hz) and 50.0 <= args.rate_hz <= 1000.0):
        raise CliError(f"--rate-hz must be within 50-1000 Hz, got {args.rate_hz:g}")
    step_s = 1.0 / args.rate_hz
    window = window_steps(step_s, steps=args.window_steps, seconds=args.window_s)
    observer = init.meta.observer if init is not None else None
    if args.observer_value:
        if init is not None:
            raise CliError(
                "--observer-value does not go with --init: the model's network learnt "
                "the outputs of the filter it records"
            )
        observer = observer_values(args.observer_value)
    spec = InputSpec(features, args.prior, step_s, vehicle, observer, observer_file, car=args.car)
    if args.car == "given":
        missing = [
            option
            for option, needed, given in (
                ("--vehicle", spec.needs_vehicle, vehicle),
                ("--observer-params", spec.needs_observer, observer_file),
            )
            if needed and given is None
        ]
        if missing:
            raise CliError(f"--car given: the model's inputs need {' and '.join(missing)}")
    check_alpha(args.interpolate)
    if args.interpolate < 1.0 and (init is None or args.normalization != "keep"):
        raise CliError(
            f"--interpolate {args.interpolate:g} moves fine-tuned weights toward --init's: "
            + ("there is no --init" if init is None else "needs --normalization keep")
        )
    keep = init.normalizer if init is not None and args.normalization == "keep" else None
    choice = DataChoice(
        data=args.data,
        val=args.val,
        test=args.test,
        split=args.split,
        val_fraction=prof.val_fraction if args.val_fraction is None else args.val_fraction,
        test_fraction=args.test_fraction,
        seed=args.seed,
        topic_map=args.topic_map,
        stride=args.stride,
        mirror=args.mirror,
        mirror_val=args.mirror_val,
        rehearse=args.rehearse,
    )
    data = load_training_data(
        choice,
        spec,
        window,
        max_stride=prof.stride,
        workers=args.workers,
        progress=not args.quiet,
        log=log,
        normalizer=keep,
    )
    dt_s = sample_period_s(data.runs)  # every bag now at step_s: a check, not a choice
    return TrainPlan(prof, base, init, tuple(features), vehicle, spec, window, run_dir, data, dt_s)


def run_config(args: argparse.Namespace, command: str, plan: TrainPlan) -> dict[str, Any]:
    """config.json: the command, its resolved options and everything the run depends on."""
    data = plan.data
    return {
        "command": command,
        "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()},
        "profile": asdict(plan.profile),
        "train_config": asdict(plan.base),
        "features": list(plan.features),
        "prior": args.prior,
        "observer": plan.spec.observer,
        "train_bags": [r.name for r in data.recorded_train_runs],
        "rehearsal_bags": [r.name for r in data.rehearsal_runs],
        "val_bags": [r.name for r in data.val_runs],
        "test_bags": [r.name for r in data.test_runs],
        # The mode the parts were really split by (chosen on all of --data, before a
        # test part was taken), not one recomputed from what training and validation kept.
        "split": data.split,
        "window_steps": plan.window,
        "data_digest": data_digest(data.runs),
        "normalizer": data.normalizer.to_dict(),
        "sample_period_s": plan.dt_s,
        "particle_threads": particle_threads(args) if args.pso else None,
        "sideslip_training": __version__,
    }
