"""The model files the ``pso_lstm`` back-end runs: shipped ones by name, or a path.

The package ships its models under ``sideslip_estimator/data/models``; ``model_file``
names one of them, a ``.safetensors`` path, or nothing (the default for what the
deployment gives, :func:`default_model`).

Beyond a fine-tuned model's recordings: a model ``sideslip-fit --bags`` fine-tuned on one
car records the range of the recordings it was fitted on (``FitRange`` in its σ). While
the input window reaches beyond it, ``pso_lstm.beyond_fit_range`` chooses: ``start``
publishes the estimate and σ of the model it was fine-tuned from (the node runs both,
every sample), ``model`` this model's with σ widened, ``auto`` (default) ``start`` when
the recordings were gentle (|a_y| under ``GENTLE_LATERAL_MPS2``) and that model is found
(``start_model_file``, or the shipped model the file names with the same training data),
else ``model``. Fine-tuned on gentle driving, a model forgets the limit the start model
knew; fitted on driving near the limit, it did better beyond its range on its own
(docs/evaluation/fit-bags, "Beyond the recordings").
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Final

import numpy as np

from sideslip_msgs_py.artifact import ArtifactError, ModelMetadata, read_artifact
from sideslip_msgs_py.uncertainty import FitRange

from .base import BackendError

SHIPPED_DIR: Final = "data/models"
BEYOND_FIT_RANGE: Final = ("auto", "start", "model")
"""``pso_lstm.beyond_fit_range`` (and ``sideslip-evaluate --beyond-fit-range``)."""
SHIPPED_MODEL: Final = f"{SHIPPED_DIR}/fleet_lstm_paper.safetensors"
"""The default model, relative to the sideslip_estimator package: needs nothing but the
measurements (no car parameters)."""
SHIPPED_OBSERVER_MODEL: Final = f"{SHIPPED_DIR}/fleet_ukf_paper.safetensors"
"""The default model when the car's ``ukf`` params file is given
(``observer_params_file``): the same inputs plus the UKF observer, more accurate where
the car's parameters are right."""


def shipped_models() -> list[str]:
    """Names of the models shipped in the package (``model_file`` accepts them)."""
    folder = resources.files("sideslip_estimator").joinpath(SHIPPED_DIR)
    if not folder.is_dir():
        return []
    return sorted(
        p.name.removesuffix(".safetensors")
        for p in folder.iterdir()
        if p.name.endswith(".safetensors")
    )


def default_model(observer_params_file: str) -> str:
    """The shipped default (relative to the package) for what the deployment gives: with
    the car's ukf params file :data:`SHIPPED_OBSERVER_MODEL`, else :data:`SHIPPED_MODEL`."""
    return SHIPPED_OBSERVER_MODEL if observer_params_file else SHIPPED_MODEL


def read_model(
    model_file: str, default: str = SHIPPED_MODEL
) -> tuple[dict[str, np.ndarray], ModelMetadata, str]:
    """Tensors, metadata and a short label of the model ``model_file`` names: a path, the
    name of a shipped model, or "" for ``default`` (a shipped path)."""
    try:
        if model_file and ("/" in model_file or model_file.endswith(".safetensors")):
            path = Path(model_file).expanduser()
            tensors, meta = read_artifact(path)
            return tensors, meta, path.name
        if model_file and model_file not in shipped_models():
            msg = (
                f"pso_lstm.model_file: {model_file!r} is neither a .safetensors path nor a "
                f"shipped model (shipped: {', '.join(shipped_models())})"
            )
            raise BackendError(msg)
        relative = f"{SHIPPED_DIR}/{model_file}.safetensors" if model_file else default
        ref = resources.files("sideslip_estimator").joinpath(relative)
        if not ref.is_file():
            msg = (
                f"pso_lstm.model_file: no model is shipped yet (expected "
                f"sideslip_estimator/{relative}); train one with `sideslip-train` "
                f"(see its --help) and set pso_lstm.model_file:=/path/to/model.safetensors"
            )
            raise BackendError(msg)
        with resources.as_file(ref) as path:
            tensors, meta = read_artifact(path)
        return tensors, meta, f"{path.name} (shipped)"
    except ArtifactError as err:
        raise BackendError(f"pso_lstm.model_file: {err}") from None


def start_model_name(meta: ModelMetadata) -> str | None:
    """The shipped model ``meta``'s model was fine-tuned from (``sideslip-train --init``),
    when that model is still shipped with the training data it had then; else None (a
    model trained from scratch, started from a file of the user's, or a start model
    since replaced)."""
    init = meta.provenance.get("init")
    if not isinstance(init, str) or not init.endswith(".safetensors"):
        return None
    name = init.removesuffix(".safetensors")
    if name not in shipped_models():
        return None
    try:
        start = read_model(name)[1]
    except BackendError:
        return None
    return name if start.training_data_digest == meta.provenance.get("init_data") else None


def hands_over(mode: str, fit: FitRange | None) -> bool:
    """Whether ``beyond_fit_range`` ``mode`` asks for the start model beyond ``fit`` (the
    model's range of recordings; None: it records none): ``start`` always, ``auto`` only
    for gentle recordings (:attr:`FitRange.gentle`: a fit on driving near the limit kept
    its own estimate better beyond its range on validation cars), ``model`` never. The
    node and ``sideslip-evaluate`` both decide by it."""
    return fit is not None and (mode == "start" or (mode == "auto" and fit.gentle))
