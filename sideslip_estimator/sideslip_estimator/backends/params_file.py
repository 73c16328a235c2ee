"""Model parameter files of the physics back-ends: a shipped name or a YAML path.

``single_track`` and ``ukf`` read a vehicle's nominal numbers from a YAML file that the
simulator package writes (the estimator never imports the simulator). ``source`` is a
path (``*.yaml``, or any existing file) or the name of a file shipped in the
``sideslip_estimator`` package under ``shipped_dir``; errors name the back-end's
``params_file`` parameter and the path or name.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from importlib import resources
from pathlib import Path

import yaml

from .base import BackendError


def read_params_file(backend: str, source: str, shipped_dir: str) -> tuple[object, str]:
    """(parsed YAML, where) of ``source``; ``where`` names the file in later errors."""
    path = Path(source)
    if path.suffix in (".yaml", ".yml") or path.exists():
        where = str(path)
        try:
            text = path.read_text()
        except OSError as err:
            msg = f"{backend}.params_file {where}: cannot read ({err.strerror})"
            raise BackendError(msg) from None
    else:
        package = resources.files("sideslip_estimator")
        ref = package.joinpath(f"{shipped_dir}/{source}.yaml")
        if not ref.is_file():
            shipped = sorted(
                p.name.removesuffix(".yaml") for p in package.joinpath(shipped_dir).iterdir()
            )
            msg = f"{backend}.params_file: no shipped {source!r} (shipped: {shipped})"
            raise BackendError(msg)
        where, text = f"{source} (shipped)", ref.read_text()
    try:
        return yaml.safe_load(text), where
    except yaml.YAMLError as err:
        raise BackendError(f"{where}: not valid YAML ({err})") from None


def check_keys(data: object, where: str, names: Iterable[str], what: str) -> dict:
    """``data`` as a mapping with exactly the keys ``names`` (else a BackendError)."""
    if not isinstance(data, dict):
        raise BackendError(f"{where}: expected a mapping of {what}")
    names = list(names)
    unknown = sorted(set(data) - set(names))
    missing = [n for n in names if n not in data]
    if unknown or missing:
        raise BackendError(f"{where}: unknown keys {unknown}, missing keys {missing}")
    return data


def finite_number(where: str, key: str, value: object) -> float:
    """``value`` as a float if it is a finite real number (bool refused), else an error."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise BackendError(f"{where}: {key} must be a finite number, got {value!r}")
    return float(value)
