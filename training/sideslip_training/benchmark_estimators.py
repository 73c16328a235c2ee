"""The estimators ``sideslip-benchmark`` scores: the networks and the physics filters.

In the tables' column order:

* ``β = 0``, the floor any estimator must beat;
* ``Kinematic (raw)`` and ``Kinematic (20-step mean)``: atan2(Y_v, X_v)
  (:func:`.evaluate.kinematic`), the baseline of every network that reads Y_v;
* ``Single-track KF`` and ``UKF``: the estimator's ``single_track`` and ``ukf``
  back-ends, fed one sample at a time through the estimator core
  (:class:`~sideslip_estimator.estimator.Estimator`: checks, alignment, window) in the
  order twist, steering, IMU of each stamp, as ``bench/offline_backends.py`` does.
  Each gets the car's true nominal parameters (a params YAML per car, written from
  :func:`sideslip_sim.single_track.estimator_parameters` and
  :func:`sideslip_sim.ukf_params.ukf_parameters` of its per-axle tyres), and the
  back-end's default noise sigmas unless ``--physics-params`` gives others;
* every network: the shipped models and each ``--model``, through
  :func:`.evaluate.predict_run` (with ``vehicle=`` when it takes one).

The baselines are computed where the runs are scored (:func:`.benchmark_scores.collect`).

This module imports ``sideslip_estimator`` (the back-ends and shipped models it
scores), unlike the rest of the training package apart from :mod:`.ukf_tuning`.
"""

from __future__ import annotations

import inspect
import multiprocessing
import sys
import tempfile
from collections.abc import Mapping, Sequence
from concurrent import futures
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import numpy as np
import numpy.typing as npt
import yaml

from sideslip_msgs_py.sample import SampleArrays

from .benchmark_data import PROG, BenchmarkError, HeldOutRun
from .config import WINDOW_STEPS
from .physics_params import nominal_parameters, params_yaml, steering_limit_m

FloatArray = npt.NDArray[np.float64]

ZERO: Final = "β = 0"
KINEMATIC_RAW: Final = "Kinematic (raw)"
SMOOTHING_STEPS: Final = 20
KINEMATIC_MEAN: Final = f"Kinematic ({SMOOTHING_STEPS}-step mean)"
SINGLE_TRACK: Final = "Single-track KF"
UKF: Final = "UKF"
PHYSICS_BACKENDS: Final = {SINGLE_TRACK: "single_track", UKF: "ukf"}
BASELINES: Final = (ZERO, KINEMATIC_RAW, KINEMATIC_MEAN)


# --- the networks ---------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Network:
    """A model artifact under its column label."""

    label: str
    path: Path
    model: Any  # SideslipNet
    meta: Any  # ModelMetadata

    @property
    def uses_lateral_velocity(self) -> bool:
        return "y_v_mps" in self.meta.channels  # read directly, by a derived input or a prior


def shipped_model_paths() -> list[Path]:
    """The models shipped with the estimator (``data/models/*.safetensors``)."""
    from importlib import resources

    folder = resources.files("sideslip_estimator").joinpath("data/models")
    return sorted(Path(str(p)) for p in folder.iterdir() if p.name.endswith(".safetensors"))


def load_networks(specs: Sequence[str], *, shipped: bool) -> list[Network]:
    """Networks of ``LABEL=PATH`` (or bare ``PATH``: label from its metadata) specs, after
    the shipped models when ``shipped``. Labels are unique and differ from the other
    estimators'; every window is the same.

    Raises:
        BenchmarkError: unreadable or malformed file, duplicate label, other windows.
    """
    from sideslip_msgs_py.artifact import ArtifactError

    from .evaluate import model_label
    from .export import load_model

    entries: list[tuple[str | None, Path]] = (
        [(None, p) for p in shipped_model_paths()] if shipped else []
    )
    for spec in specs:
        label, sep, path = spec.partition("=")
        if not sep:
            label, path = "", spec
        if sep and not label.strip():
            raise BenchmarkError(f"--model {spec!r}: empty label (expected LABEL=PATH)")
        if not path:
            raise BenchmarkError(f"--model {spec!r}: no path (expected LABEL=PATH)")
        entries.append((label.strip() or None, Path(path)))
    networks: list[Network] = []
    for label, path in entries:
        try:
            model, meta = load_model(path)
        except (ArtifactError, OSError) as err:
            raise BenchmarkError(f"--model {path}: cannot load ({err})") from None
        networks.append(Network(label or model_label(meta), path, model, meta))
    _disambiguate(networks, explicit={lab for lab, _ in entries if lab})
    taken = set(BASELINES) | set(PHYSICS_BACKENDS)
    for n in networks:
        if n.label in taken:
            raise BenchmarkError(
                f"--model {n.path}: label {n.label!r} is taken by another estimator or model"
            )
        taken.add(n.label)
    windows = {n.meta.window_steps for n in networks}
    if len(windows) > 1:
        which = ", ".join(f"{n.label}: {n.meta.window_steps}" for n in networks)
        raise BenchmarkError(f"models with different windows ({which}); score them separately")
    return networks


def _disambiguate(networks: list[Network], explicit: set[str]) -> None:
    """Two models whose metadata gives the same label: tag each with its file stem."""
    labels = [n.label for n in networks]
    for i, n in enumerate(networks):
        if labels.count(n.label) > 1 and n.label not in explicit:
            object.__setattr__(networks[i], "label", f"{n.label} ({n.path.stem})")


def predict(network: Network, run: HeldOutRun, *, mirror_average: bool | str = False) -> FloatArray:
    """The network's β̂ [rad] of ``run`` (samples[window-1:]) through predict_run, with the
    car's parameters where predict_run takes a ``vehicle`` (vehicle-conditioned models);
    ``mirror_average``: averaged with its mirror image (``pso_lstm.mirror_average``: a
    bool, or ``auto`` / ``yes`` / ``no``)."""
    from .evaluate import predict_run

    if "vehicle" in inspect.signature(predict_run).parameters:
        from sideslip_sim.vehicle import vehicle_from_dict

        vehicle = vehicle_from_dict(dict(run.vehicle))
        return predict_run(
            network.model, network.meta, run.run, vehicle=vehicle, mirror_average=mirror_average
        )
    return predict_run(network.model, network.meta, run.run, mirror_average=mirror_average)


# --- the physics filters --------------------------------------------------------------------


@dataclass(frozen=True)
class PhysicsFilter:
    """A physics back-end under its column label, with the noise settings it runs with."""

    label: str
    backend: str
    values: dict[str, Any]
    """Back-end parameters other than ``params_file`` (the back-end's defaults overlaid
    with ``--physics-params``), as the back-end reads them."""


def read_physics_params(path: Path | None) -> dict[str, dict[str, Any]]:
    """``{backend: {parameter: value}}`` from a ``--physics-params`` YAML (or {})."""
    if path is None:
        return {}
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as err:
        raise BenchmarkError(f"--physics-params {path}: cannot read ({err.strerror})") from None
    except yaml.YAMLError as err:
        raise BenchmarkError(f"--physics-params {path}: not valid YAML ({err})") from None
    if data is None:
        return {}
    known = set(PHYSICS_BACKENDS.values())
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        raise BenchmarkError(
            f"--physics-params {path}: expected a mapping of back-end ({', '.join(sorted(known))}) "
            "to a mapping of parameter values"
        )
    unknown = sorted(set(data) - known)
    if unknown:
        raise BenchmarkError(
            f"--physics-params {path}: unknown back-end(s) {unknown} (known: "
            f"{', '.join(sorted(known))})"
        )
    for backend, values in data.items():
        if "params_file" in values:
            raise BenchmarkError(
                f"--physics-params {path}: {backend}.params_file is not set here: each car's "
                "filters get its own nominal parameters"
            )
    return data


def physics_filters(
    tuned: Mapping[str, Mapping[str, Any]],
) -> tuple[list[PhysicsFilter], list[str]]:
    """The physics filters that can run here, and a note for each that cannot.

    Raises:
        BenchmarkError: a ``--physics-params`` value the back-end refuses.
    """
    import importlib.util

    from sideslip_estimator.backends import BACKENDS, BackendError
    from sideslip_estimator.backends.base import parameter_values

    filters: list[PhysicsFilter] = []
    notes: list[str] = []
    for label, backend in PHYSICS_BACKENDS.items():
        if backend not in BACKENDS:
            notes.append(f"{label}: skipped, the estimator has no {backend!r} back-end")
            continue
        if backend == "ukf" and importlib.util.find_spec("sideslip_sim.ukf_params") is None:
            notes.append(f"{label}: skipped, sideslip_sim.ukf_params is missing")
            continue
        specs = BACKENDS[backend].parameters
        try:
            values = parameter_values(backend, specs, dict(tuned.get(backend, {})))
        except BackendError as err:
            raise BenchmarkError(f"--physics-params: {err}") from None
        del values["params_file"]
        filters.append(PhysicsFilter(label, backend, values))
    return filters, notes


def prepare_physics(
    filters: list[PhysicsFilter], runs: Sequence[HeldOutRun], notes: list[str]
) -> dict[tuple[str, str], dict[str, Any]]:
    """Each filter's nominal parameters per car, each checked by building the back-end;
    a filter whose back-end cannot be built here (a missing library) is dropped with a
    note."""
    from sideslip_estimator.backends import BackendError, create_backend

    cars = {r.vehicle_name: r.vehicle for r in runs}
    params: dict[tuple[str, str], dict[str, Any]] = {}
    for f in list(filters):
        try:
            for name, vehicle in cars.items():
                params[(f.label, name)] = nominal_parameters(f.backend, vehicle)
                with tempfile.TemporaryDirectory() as tmp:
                    path = Path(tmp) / f"{name}.yaml"
                    path.write_text(params_yaml(f.backend, name, params[(f.label, name)], PROG))
                    create_backend(f.backend, {**f.values, "params_file": str(path)}, WINDOW_STEPS)
        except ImportError as err:
            notes.append(f"{f.label}: skipped, {err}")
            filters.remove(f)
        except BackendError as err:
            raise BenchmarkError(f"{f.label} on {name}: {err}") from None
    return params


def write_params_files(
    params: Mapping[tuple[str, str], Mapping[str, Any]], folder: Path
) -> dict[tuple[str, str], Path]:
    """``params`` of each (filter label, car) as ``folder/<car>.<back-end>.yaml``; the paths."""
    paths: dict[tuple[str, str], Path] = {}
    for (label, vehicle), values in params.items():
        backend = PHYSICS_BACKENDS[label]
        paths[(label, vehicle)] = folder / f"{vehicle}.{backend}.yaml"
        paths[(label, vehicle)].write_text(params_yaml(backend, vehicle, values, PROG))
    return paths


def replay_filter(
    samples: SampleArrays,
    backend: str,
    values: Mapping[str, Any],
    window_steps: int,
    stl_limit_m: float,
) -> FloatArray:
    """β̂ [rad] of every sample (NaN where none) from the estimator core fed the run one
    sample at a time: twist, steering, then the IMU of the same stamp (the order of
    ``bench/offline_backends.py``, so every IMU sample aligns with its own step), with
    the steering limit ``stl_limit_m`` [m] (:func:`steering_limit_m`) and the node's
    other defaults. Rejected samples get no estimate."""
    from sideslip_estimator.backends import create_backend
    from sideslip_estimator.estimator import Estimator, EstimatorParams
    from sideslip_estimator.inputs import InputLimits
    from sideslip_estimator.replay import replay, replay_columns

    est = Estimator(
        create_backend(backend, dict(values), window_steps),
        EstimatorParams(window_steps=window_steps, limits=InputLimits(stl_m=stl_limit_m)),
    )
    return replay(est, replay_columns(samples)).beta_rad


def run_physics(
    runs: Sequence[HeldOutRun],
    filters: Sequence[PhysicsFilter],
    params_files: Mapping[tuple[str, str], Path],
    *,
    window_steps: int,
    jobs: int,
    progress: bool,
) -> dict[tuple[str, str], FloatArray]:
    """β̂ per sample of every (run, filter label), ``jobs`` worker processes (fork)."""
    from tqdm import tqdm

    # (key, replay_filter arguments) per run and filter; the UKF's (longest) first.
    tasks = [
        (
            (r.name, f.label),
            (
                r.run.samples,
                f.backend,
                {**f.values, "params_file": str(params_files[(f.label, r.vehicle_name)])},
                window_steps,
                steering_limit_m(r.vehicle),
            ),
        )
        for f in sorted(filters, key=lambda f: f.backend != "ukf")
        for r in runs
    ]
    out: dict[tuple[str, str], FloatArray] = {}
    bar = tqdm(
        total=len(tasks), unit="run", desc="physics filters", disable=not progress, file=sys.stderr
    )
    try:
        if jobs <= 1 or len(tasks) <= 1:
            for key, task in tasks:
                out[key] = replay_filter(*task)
                bar.update()
        else:
            ctx = multiprocessing.get_context("fork")
            with futures.ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
                pending = {pool.submit(replay_filter, *task): key for key, task in tasks}
                for fut in futures.as_completed(pending):
                    out[pending[fut]] = fut.result()
                    bar.update()
    finally:
        bar.close()
    return out
