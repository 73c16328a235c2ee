"""The UKF observer's outputs over a whole run, for models anchored on it.

A model whose inputs or prior read ``ukf.*`` columns
(:data:`sideslip_msgs_py.model_inputs.OBSERVER_COLUMNS`) needs, for every sample of a
run, what the estimator's ``ukf`` back-end reports after that sample. Here the back-end
runs inside the estimator core exactly as the node and the ``pso_lstm`` back-end run it
(same checks, same window restarts, one sample at a time), with the car's true nominal
parameters (from the bag's vehicle record) or a given ``ukf`` params file (a real
recording). Values: the parameters of the ``ukf`` back-end other than ``params_file``,
stored in the model file (``ModelMetadata.observer``) so deployment runs the same filter.

The filter costs about 0.2 ms per sample in Python, so the columns of a run are cached
on disk, keyed by a digest of the samples, the params file's contents and the values
(``$SIDESLIP_CACHE`` or ``~/.cache/sideslip``/observer); :func:`precompute` fills the
cache for many runs in worker processes. The filter is exactly symmetric (on a run mirrored
left-right its β̂ is minus the run's to 1e-14 rad, docs/evaluation/direction), so a run's
mirror image (``sideslip-train --mirror``, ``--mirror-val``) is not filtered again: its
columns are the run's, the odd ones negated.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import json
import multiprocessing
import os
import sys
import tempfile
from collections.abc import Mapping, Sequence
from concurrent import futures
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import numpy.typing as npt
import yaml

from sideslip_msgs_py.fleet_envelope import FleetEnvelope
from sideslip_msgs_py.mirror import ODD_INPUTS, mirrored
from sideslip_msgs_py.model_inputs import OBSERVER_COLUMNS

from .config import WINDOW_STEPS
from .dataset import DatasetError, filtered_span

if TYPE_CHECKING:
    from .dataset import Run

FloatArray = npt.NDArray[np.float64]
BACKEND: Final = "ukf"
CACHE_VERSION: Final = 2


def default_values() -> dict[str, Any]:
    """The ``ukf`` back-end's default parameters, ``params_file`` left out."""
    from sideslip_estimator.backends import BACKENDS
    from sideslip_estimator.backends.base import parameter_values

    values = parameter_values(BACKEND, BACKENDS[BACKEND].parameters, {})
    del values["params_file"]
    return values


def check_values(values: Mapping[str, Any]) -> dict[str, Any]:
    """``values`` completed with the back-end's defaults and checked by its types."""
    from sideslip_estimator.backends import BACKENDS, BackendError
    from sideslip_estimator.backends.base import parameter_values

    if "params_file" in values:
        raise DatasetError("observer values: params_file is per car, not a model setting")
    try:
        out = parameter_values(BACKEND, BACKENDS[BACKEND].parameters, dict(values))
    except BackendError as err:
        raise DatasetError(f"observer values: {err}") from None
    del out["params_file"]
    return out


def params_of_vehicle(vehicle: Mapping[str, Any]) -> dict[str, Any]:
    """The ``ukf`` params file contents of a simulated car (its true nominal values)."""
    return dict(_params_of_car(json.dumps(dict(vehicle), sort_keys=True, default=str)))


@functools.lru_cache(maxsize=256)
def _params_of_car(vehicle_json: str) -> dict[str, Any]:
    # One Magic Formula fit per car (scipy, tens of ms), not one per run and call: the
    # trainer asks for a run's columns once for its inputs and once for its prior.
    from .physics_params import nominal_parameters

    return nominal_parameters(BACKEND, json.loads(vehicle_json))


def described_half(bag: str) -> bool:
    """Whether ``--car mixed`` gives the bag ``bag`` its described car: by a digest of the
    name, not by position, so that a bag keeps its side whatever else is loaded beside it
    and a run's segments and mirror image share it."""
    return hashlib.sha256(bag.encode()).digest()[0] % 2 == 1


def params_of_described(vehicle: Mapping[str, Any]) -> dict[str, Any]:
    """The ``ukf`` params of the car a simulated car's description stands for: what a
    user who knows only the description gives the node (:mod:`sideslip_sim.described_car`)."""
    params = _params_of_described(json.dumps(dict(vehicle), sort_keys=True, default=str))
    return {**params, "axles_from": "description"}


def axles_from(run: Run, params_file: str | None, *, car: str = "recorded") -> str:
    """Where the axle curves of ``run``'s UKF come from (``ukf_model.AXLES_FROM``), as
    :func:`run_params` gives that filter its file: for ``description`` a model's σ for
    described files is published (``Uncertainty.for_axles``)."""
    from sideslip_estimator.backends.ukf_model import AXLES_FROM

    value = run_params(run, params_file, car=car)[0].get("axles_from", "vehicle")
    if value not in AXLES_FROM:
        where = params_file or run.name
        raise DatasetError(f"{where}: axles_from must be one of {AXLES_FROM}, got {value!r}")
    return str(value)


@functools.lru_cache(maxsize=256)
def _params_of_described(vehicle_json: str) -> dict[str, Any]:
    from sideslip_sim.described_car import described_from_mapping
    from sideslip_sim.vehicle import vehicle_record

    vehicle = json.loads(vehicle_json)
    name = str(vehicle.get("name", "car"))
    try:
        car = described_from_mapping(vehicle, name, name=f"{name}_described")
    except ValueError as err:  # not a description, or no plausible car
        raise DatasetError(str(err)) from None
    return params_of_vehicle(vehicle_record(car))


def run_params(
    run: Run, params_file: str | None, *, car: str = "recorded"
) -> tuple[dict[str, Any], float]:
    """(``ukf`` params file contents, steering limit [m]) for ``run``: by ``car``
    (:data:`~sideslip_training.inputs.CAR_SOURCES`) from its bag's vehicle record
    (``recorded``: the simulation's true parameters; ``described``: the car its
    description stands for, :mod:`sideslip_sim.described_car`), else from
    ``params_file`` (a recording of a real car; ``given``: for every run).

    The steering limit, a node setting and not a car parameter the model learns, comes
    from the record where there is one."""
    from sideslip_estimator.inputs import InputLimits

    from .physics_params import steering_limit_m

    car = run.car_source or car
    vehicle = run.run_metadata.get("vehicle")
    recorded = isinstance(vehicle, Mapping)
    if car == "mixed":
        car = "described" if described_half(run.bag) else "recorded"
    if recorded and car == "recorded":
        return params_of_vehicle(vehicle), steering_limit_m(vehicle)
    if recorded and car == "described":
        return params_of_described(vehicle), steering_limit_m(vehicle)
    if params_file is None:
        raise DatasetError(
            f"{run.name}: the model reads the UKF observer, but "
            + ("the given car is asked for" if recorded else "the bag records no vehicle")
            + "; give the car's ukf params file"
        )
    return read_params_file(params_file), (
        steering_limit_m(vehicle) if recorded else InputLimits().stl_m
    )


def read_params_file(path: str) -> dict[str, Any]:
    """A ``ukf`` params file's contents."""
    try:
        data = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise DatasetError(f"observer params file {path}: cannot read ({err})") from None
    if not isinstance(data, dict):
        raise DatasetError(f"observer params file {path}: expected a mapping of parameters")
    return data


def training_envelope(
    runs: Sequence[Run], params_file: str | None, *, car: str = "recorded"
) -> FleetEnvelope:
    """The range of the cars of ``runs`` (:mod:`sideslip_msgs_py.fleet_envelope`), from
    their ``ukf`` params as the observer columns were computed with."""
    return FleetEnvelope.of_cars(run_params(run, params_file, car=car)[0] for run in runs)


def _digest(run: Run, params: Mapping[str, Any], values: Mapping[str, Any], stl: float) -> str:
    h = hashlib.sha256()
    # Where the axle curves came from is not read by the filter: the same columns.
    filtered = {k: v for k, v in params.items() if k != "axles_from"}
    key = {"v": CACHE_VERSION, "params": filtered, "values": values, "stl": stl}
    h.update(json.dumps(key, sort_keys=True, default=str).encode())
    s = run.samples
    for c in ("stamp_ns", "x_v_mps", "x_a_mps2", "y_a_mps2", "yaw_rate_radps", "stl_m"):
        h.update(np.ascontiguousarray(getattr(s, c)).tobytes())
    return h.hexdigest()[:24]


def cache_dir() -> Path:
    root = os.environ.get("SIDESLIP_CACHE") or Path.home() / ".cache" / "sideslip"
    return Path(root) / "observer"


def compute(
    run: Run, params: Mapping[str, Any], values: Mapping[str, Any], stl_limit_m: float
) -> dict[str, FloatArray]:
    """The observer columns of every sample of ``run`` (NaN where the filter gives none)."""
    from sideslip_estimator.backends import create_backend
    from sideslip_estimator.estimator import Estimator, EstimatorParams
    from sideslip_estimator.inputs import InputLimits
    from sideslip_estimator.replay import replay, replay_columns

    from .physics_params import params_yaml

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "observer.ukf.yaml"
        path.write_text(
            params_yaml(
                BACKEND, str(params.get("name", "car")), params, "sideslip-train (UKF observer)"
            )
        )
        ukf = create_backend(BACKEND, {**values, "params_file": str(path)}, WINDOW_STEPS)
    recorder = Recorder(ukf)
    est = Estimator(
        recorder, EstimatorParams(window_steps=WINDOW_STEPS, limits=InputLimits(stl_m=stl_limit_m))
    )
    replay(est, replay_columns(run.samples))
    return recorder.columns(run.samples.stamp_ns)


class Recorder:
    """A ``ukf`` back-end that remembers its output after every sample, by stamp."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.name = inner.name
        self.model_id = inner.model_id
        self._rows: dict[int, tuple[float, ...]] = {}

    def reset(self) -> None:
        self.inner.reset()

    def update(self, rows: FloatArray, stamps_ns: npt.NDArray[np.int64]) -> Any:
        out = self.inner.update(rows, stamps_ns)
        self._rows[int(stamps_ns[-1])] = self.inner.observer_row(out)
        return out

    def columns(self, stamps_ns: npt.NDArray[np.int64]) -> dict[str, FloatArray]:
        table = np.full((len(stamps_ns), len(OBSERVER_COLUMNS)), np.nan)
        for i, stamp in enumerate(stamps_ns.tolist()):
            got = self._rows.get(int(stamp))
            if got is not None:
                table[i] = got
        return {c: table[:, j].copy() for j, c in enumerate(OBSERVER_COLUMNS)}


def columns(
    run: Run, values: Mapping[str, Any], params_file: str | None = None, car: str = "recorded"
) -> dict[str, FloatArray]:
    """The observer columns of ``run``, from the disk cache when there. A run cut out of
    a recording (:attr:`Run.recording`) reads them off the whole recording's filter, which
    ran through the samples before the cut as the node did."""
    if run.recording is not None:
        _, offset = filtered_span(run)  # checks that the samples are the recording's
        stop = offset + len(run.samples.stamp_ns)
        got = columns(recording_of(run), values, params_file, car)
        return {c: v[offset:stop] for c, v in got.items()}
    params, stl = run_params(run, params_file, car=car)
    path = cache_dir() / f"{_digest(run, params, values, stl)}.npz"
    recent = _RECENT.get(path)
    if recent is not None:
        return recent
    out = _load(path, len(run.samples.stamp_ns))
    if out is None:
        twin_path = cache_dir() / f"{_mirror_digest(run, params, values, stl)}.npz"
        twin = _load(twin_path, len(run.samples.stamp_ns))
        out = None if twin is None else _negate_odd(twin)
    if out is None:
        out = compute(run, params, values, stl)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez(tmp, **out)
        tmp.replace(path)
    _RECENT[path] = out
    while len(_RECENT) > _RECENT_RUNS:
        _RECENT.pop(next(iter(_RECENT)))
    return out


def recording_of(run: Run) -> Run:
    """The whole recording ``run`` was cut from, as a run of its own (``run`` itself when
    it was not cut). The filter runs over it once for all its pieces."""
    if run.recording is None:
        return run
    return dataclasses.replace(run, samples=run.recording, recording=None, offset=0)


def _mirror_digest(
    run: Run, params: Mapping[str, Any], values: Mapping[str, Any], stl: float
) -> str:
    """The cache key of ``run``'s mirror image."""
    return _digest(dataclasses.replace(run, samples=mirrored(run.samples)), params, values, stl)


def _negate_odd(columns: Mapping[str, FloatArray]) -> dict[str, FloatArray]:
    """The observer columns of the mirrored run: the odd ones negated, μ̂ kept."""
    return {c: -v if c in ODD_INPUTS else v for c, v in columns.items()}


def without_mirror_images(
    runs: Sequence[Run], values: Mapping[str, Any], params_file: str | None, car: str
) -> list[Run]:
    """``runs`` less each run whose mirror image comes before it (same car, the lateral
    channels negated): :func:`columns` derives its columns from that image's."""
    seen: set[str] = set()
    kept = []
    for run in runs:
        params, stl = run_params(run, params_file, car=car)
        digest = _digest(run, params, values, stl)
        if digest in seen or _mirror_digest(run, params, values, stl) in seen:
            continue  # the same samples (pieces' recordings), or their mirror image
        seen.add(digest)
        kept.append(run)
    return kept


_RECENT_RUNS: Final = 4
_RECENT: dict[Path, dict[str, FloatArray]] = {}
"""The last runs' columns: the trainer reads a run's inputs and its prior in turn."""


def _load(path: Path, samples: int) -> dict[str, FloatArray] | None:
    """A cache entry's columns, or None when it is missing or damaged."""
    if not path.exists():
        return None
    try:
        with np.load(path) as data:
            got = {c: data[c] for c in OBSERVER_COLUMNS}
    except (OSError, KeyError, ValueError):
        return None  # a damaged cache entry: compute it again
    return got if all(len(v) == samples for v in got.values()) else None


def _fill(run: Run, values: Mapping[str, Any], params_file: str | None, car: str) -> None:
    columns(run, values, params_file, car)


def precompute(
    runs: Sequence[Run],
    values: Mapping[str, Any],
    params_file: str | None = None,
    *,
    car: str = "recorded",
    jobs: int = 1,
    progress: bool = True,
) -> None:
    """Fill the cache for ``runs`` with ``jobs`` worker processes (fork); runs cut out of
    one recording are filtered once, over the recording; a mirror image of an earlier
    run is not filtered (:func:`without_mirror_images`)."""
    from tqdm import tqdm

    wholes = {id(r.recording): recording_of(r) for r in runs if r.recording is not None}
    runs = [*(r for r in runs if r.recording is None), *wholes.values()]
    runs = without_mirror_images(runs, values, params_file, car)

    bar = tqdm(
        total=len(runs), unit="run", desc="UKF observer", disable=not progress, file=sys.stderr
    )
    try:
        if jobs <= 1 or len(runs) <= 1:
            for r in runs:
                _fill(r, values, params_file, car)
                bar.update()
            return
        ctx = multiprocessing.get_context("fork")
        with futures.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            pending = [pool.submit(_fill, r, values, params_file, car) for r in runs]
            for fut in futures.as_completed(pending):
                fut.result()
                bar.update()
    finally:
        bar.close()
