"""Fine-tuning: ``sideslip-train --init MODEL`` starts from a trained model's weights.

The model fixes what its weights mean: architecture, hidden units, layers, inputs,
prior, window and rate. Options left out are taken from it; options that contradict
it are refused with one line naming both values (training would otherwise start from
weights that read other inputs, and silently learn from scratch or worse).

Normalisation (``--normalization``): ``keep`` (the default) z-scores the new data with
the model's own statistics, so the first epoch starts from exactly the model's answer;
``refit`` fits them on the new training data, as a model from scratch would, which
shifts every input the weights see. docs/training.md records the measurement behind
the default.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sideslip_msgs_py.artifact import ModelMetadata
from sideslip_msgs_py.model_inputs import INPUT_SETS, input_set

from .export import load_model
from .model import SideslipNet
from .normalize import Normalizer

NORMALIZATION_POLICIES = ("keep", "refit")


class InitError(ValueError):
    """A model that cannot start this training (the message is one line)."""


@dataclass(frozen=True)
class InitModel:
    """The model a fine-tuning starts from."""

    path: Path
    net: SideslipNet
    meta: ModelMetadata

    @property
    def normalizer(self) -> Normalizer:
        """The model's own z-score statistics (the ``keep`` policy)."""
        m = self.meta
        return Normalizer(
            tuple(m.features),
            np.asarray(m.feature_mean, dtype=np.float64),
            np.asarray(m.feature_std, dtype=np.float64),
            float(m.beta_mean),
            float(m.beta_std),
        )


def resolve(spec: str | Path, option: str = "--init") -> Path:
    """A model file: a path, or the name of a model shipped with the estimator; an
    :class:`InitError` naming ``option`` (the command-line option it came from) else."""
    path = Path(spec)
    if path.is_file():
        return path
    from importlib import resources

    folder = resources.files("sideslip_estimator").joinpath("data/models")
    shipped = sorted(p.name.removesuffix(".safetensors") for p in folder.iterdir())
    name = path.name.removesuffix(".safetensors")
    if str(spec) == name and name in shipped:
        return Path(str(folder.joinpath(f"{name}.safetensors")))
    raise InitError(
        f"{option} {spec}: no such model file, nor a shipped model (shipped: {', '.join(shipped)})"
    )


def load_init(spec: str | Path) -> InitModel:
    from sideslip_msgs_py.artifact import ArtifactError

    path = resolve(spec)
    try:
        net, meta = load_model(path)
    except ArtifactError as err:
        raise InitError(f"--init {spec}: {err}") from None
    return InitModel(path, net, meta)


def _features_name(features: tuple[str, ...]) -> str:
    named = [n for n, f in INPUT_SETS.items() if tuple(f) == features]
    return named[0] if named else ",".join(features)


def check_fit(
    init: InitModel,
    *,
    architecture: str | None,
    features: str | None,
    prior: str | None,
    hidden_units: int | None,
    rate_hz: float | None,
    window_steps: int | None,
    pso: bool,
) -> None:
    """Refuse options that contradict the model (None: not given, the model's is used)."""
    m, name = init.meta, init.path.name
    mine = _features_name(tuple(m.features))
    conflicts = []
    if pso:
        conflicts.append("--pso searches the hidden units, which the model fixes")
    if architecture is not None and architecture != m.architecture:
        conflicts.append(f"--model {architecture} (the model is {m.architecture})")
    if features is not None and tuple(input_set(features)) != tuple(m.features):
        conflicts.append(f"--features {features} (the model reads {mine})")
    if prior is not None and prior != m.prior:
        conflicts.append(f"--prior {prior} (the model's is {m.prior})")
    if hidden_units is not None and hidden_units != m.hidden_units:
        conflicts.append(f"--hidden-units {hidden_units} (the model has {m.hidden_units})")
    if rate_hz is not None and not math.isclose(rate_hz * m.dt_s, 1.0, rel_tol=1e-6):
        conflicts.append(f"--rate-hz {rate_hz:g} (the model runs at {1 / m.dt_s:g} Hz)")
    if window_steps is not None and window_steps != m.window_steps:
        conflicts.append(f"a window of {window_steps} steps (the model's is {m.window_steps})")
    if conflicts:
        raise InitError(f"--init {name} does not fit: {'; '.join(conflicts)}")
