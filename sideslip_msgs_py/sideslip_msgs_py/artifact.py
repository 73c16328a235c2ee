"""The model artifact: one ``.safetensors`` file of float32 weights plus JSON metadata.

The contract between the trainer (which writes it) and the estimator (which reads it);
neither imports the other. Layout of the file:

* tensors named as ``torch.nn.LSTM`` / ``torch.nn.Linear`` ``state_dict`` keys of a
  network whose attributes are ``lstm`` and ``head`` (:func:`expected_tensors`);
* the safetensors header's ``__metadata__`` (a string → string map) holds
  ``format_version`` (``"1"``) and ``sideslip.model``: :class:`ModelMetadata` as JSON.

Reading executes no code (no pickle, no TorchScript): safetensors is a JSON header and
raw little-endian arrays. Every refusal is an :class:`ArtifactError` naming the file.

The network: inputs are the window's ``features`` columns (oldest row first, one row
per ``dt_s``), each z-scored as ``(x − feature_mean) / feature_std`` in float64 and
rounded once to float32 (:func:`zscore`); its scalar output ``y`` is the z-scored β,
so β [rad] = ``y · beta_std + beta_mean`` (:func:`denormalize_beta`).

safetensors is imported when a file is read or written, not with this module, so code
that only names these types (the estimator's back-end registry) does not need it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt

# The metadata and the errors are part of this module's API (the file format); they
# live in model_metadata.py so that each module holds one idea.
from .model_metadata import (
    ARCHITECTURES,
    FORMAT_VERSION,
    METADATA_KEY,
    VALIDATION_RMSE_KEY,
    VERSION_KEY,
    ArtifactError,
    ArtifactExistsError,
    ModelMetadata,
)

DTYPE: Final = np.dtype(np.float32)


def expected_tensors(meta: ModelMetadata) -> dict[str, tuple[int, ...]]:
    """Tensor name → shape of the network ``meta`` describes, in ``state_dict`` order.

    ``torch.nn.LSTM`` naming under ``lstm.`` (gates stacked i, f, g, o along the first
    axis, hence 4H), ``_reverse`` for bilstm's backward direction, then the head.
    """
    h, d = meta.hidden_units, meta.directions
    shapes: dict[str, tuple[int, ...]] = {}
    for k in range(meta.layers):
        n_in = len(meta.features) if k == 0 else d * h
        for suffix in ("", "_reverse")[:d]:
            shapes[f"lstm.weight_ih_l{k}{suffix}"] = (4 * h, n_in)
            shapes[f"lstm.weight_hh_l{k}{suffix}"] = (4 * h, h)
            shapes[f"lstm.bias_ih_l{k}{suffix}"] = (4 * h,)
            shapes[f"lstm.bias_hh_l{k}{suffix}"] = (4 * h,)
    shapes["head.weight"] = (1, d * h)
    shapes["head.bias"] = (1,)
    return shapes


def _check_names(where: str, names: set[str], expected: dict[str, tuple[int, ...]]) -> None:
    missing = [n for n in expected if n not in names]
    extra = sorted(names - set(expected))
    if missing or extra:
        msg = f"{where}: tensors do not match the metadata: missing {missing}, extra {extra}"
        raise ArtifactError(msg)


def _check_tensors(where: str, tensors: dict[str, np.ndarray], meta: ModelMetadata) -> None:
    expected = expected_tensors(meta)
    _check_names(where, set(tensors), expected)
    for name, shape in expected.items():
        t = tensors[name]
        if not isinstance(t, np.ndarray):
            raise ArtifactError(f"{where}: tensor {name} is a {type(t).__name__}, not an ndarray")
        if t.dtype != DTYPE:
            raise ArtifactError(f"{where}: tensor {name} has dtype {t.dtype}, expected float32")
        if t.shape != shape:
            msg = f"{where}: tensor {name} has shape {t.shape}, expected {shape}"
            raise ArtifactError(msg)
        if not np.isfinite(t).all():
            raise ArtifactError(f"{where}: tensor {name} holds NaN or inf")


def _safetensors() -> Any:
    try:
        import safetensors
        import safetensors.numpy
    except ImportError:
        msg = "model artifacts need the safetensors package (pip install safetensors)"
        raise ArtifactError(msg) from None
    return safetensors


def write_artifact(
    path: str | os.PathLike[str],
    tensors: dict[str, np.ndarray],
    meta: ModelMetadata,
    *,
    force: bool = False,
) -> Path:
    """Write ``tensors`` (float32, named as :func:`expected_tensors`) and ``meta`` to ``path``.

    Refuses an existing ``path`` unless ``force`` (:class:`ArtifactExistsError`), and
    tensors that do not match ``meta`` before anything is written. The file appears
    whole or not at all: written next to ``path``, read back, then renamed over it.
    Returns the path.
    """
    path = Path(path)
    if path.exists() and not force:
        raise ArtifactExistsError(f"{path}: exists (pass force to replace it)")
    if path.is_dir():
        raise ArtifactError(f"{path}: is a directory, not a model file")
    _check_tensors(str(path), tensors, meta)
    st = _safetensors()
    ordered = {name: np.ascontiguousarray(tensors[name]) for name in expected_tensors(meta)}
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        st.numpy.save_file(ordered, tmp, metadata=meta.to_header())
        read_artifact(tmp)  # never leave a file the reader refuses
        os.replace(tmp, path)
    except OSError as err:
        raise ArtifactError(f"{path}: cannot write ({err.strerror or err})") from None
    finally:
        tmp.unlink(missing_ok=True)
    return path


def read_artifact(path: str | os.PathLike[str]) -> tuple[dict[str, np.ndarray], ModelMetadata]:
    """The tensors (float32 arrays) and metadata of the artifact at ``path``.

    Executes no code from the file. Raises :class:`ArtifactError` naming ``path`` when
    it is missing, not a safetensors file, lacks sideslip metadata, has an unknown
    format version or invalid metadata, or its tensors are missing, extra, of the wrong
    shape or dtype, or hold NaN/inf.
    """
    path = Path(path)
    where = str(path)
    if not path.is_file():
        why = "no such file" if not path.exists() else "not a regular file"
        raise ArtifactError(f"{where}: {why}")
    st = _safetensors()
    try:
        with st.safe_open(path, framework="numpy") as f:
            header = f.metadata()
            names = set(f.keys())
            try:
                meta = ModelMetadata.from_header(header)
            except ArtifactError as err:
                raise ArtifactError(f"{where}: {err}") from None
            expected = expected_tensors(meta)
            _check_names(where, names, expected)
            for name, shape in expected.items():
                sl = f.get_slice(name)
                if sl.get_dtype() != "F32":
                    msg = f"{where}: tensor {name} has dtype {sl.get_dtype()}, expected F32"
                    raise ArtifactError(msg)
                if tuple(sl.get_shape()) != shape:
                    msg = f"{where}: tensor {name} has shape {tuple(sl.get_shape())}, "
                    raise ArtifactError(msg + f"expected {shape}")
            tensors = {name: f.get_tensor(name) for name in expected}
    except OSError as err:
        raise ArtifactError(f"{where}: cannot read ({err.strerror or err})") from None
    except ArtifactError:
        raise
    except Exception as err:  # safetensors' SafetensorError: a malformed header or body
        msg = f"{where}: not a safetensors file ({type(err).__name__}: {err})"
        raise ArtifactError(msg) from None
    _check_tensors(where, tensors, meta)
    return tensors, meta


def zscore(
    values: npt.ArrayLike,
    mean: npt.ArrayLike,
    std: npt.ArrayLike,
) -> npt.NDArray[np.float32]:
    """The network input ``(values − mean) / std``: computed in float64, rounded once to
    float32. ``mean``/``std`` broadcast over the last axis (one per feature)."""
    x = np.asarray(values, dtype=np.float64)
    return ((x - np.asarray(mean, np.float64)) / np.asarray(std, np.float64)).astype(np.float32)


def denormalize_beta(y: float, meta: ModelMetadata) -> float:
    """β [rad] from the network's z-scored output ``y`` (float64 arithmetic)."""
    return float(y) * meta.beta_std + meta.beta_mean


__all__ = [
    "ARCHITECTURES",
    "FORMAT_VERSION",
    "METADATA_KEY",
    "VALIDATION_RMSE_KEY",
    "VERSION_KEY",
    "ArtifactError",
    "ArtifactExistsError",
    "ModelMetadata",
    "denormalize_beta",
    "expected_tensors",
    "read_artifact",
    "write_artifact",
    "zscore",
]
