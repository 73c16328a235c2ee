"""What a PSO run leaves behind, as strict JSON: its search space, history and state.

:mod:`.pso` runs the swarm; this module holds the records it produces and reads back:

- :class:`Dimension` (one searched quantity with its bounds) and :func:`decode`, because
  the search space is saved with every history and a saved state decodes its best;
- :class:`ParticleRecord` (one evaluation), :class:`IterationRecord` (one evaluated batch)
  and :class:`PsoHistory` (all of them, iteration by iteration);
- :class:`PsoState`, the swarm after an iteration: everything needed to resume
  (positions, velocities, personal bests, the random generator's state, the history).

Every record has ``to_dict``/``from_dict``; the history and the state also ``to_json``/
``from_json``, tagged with a format name and version. JSON has no infinity, so a +inf
fitness (a failed or non-finite evaluation) is written as ``null`` and read back as +inf.

:mod:`.pso` re-exports every public name here, so ``from sideslip_training.pso import
PsoState`` keeps working; the dependency runs one way (pso → pso_records).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from sideslip_training.config import PsoSettings

Params = dict[str, float | int]
"""One particle decoded for evaluation: dimension name → value (int for integer dims)."""

_STATE_FORMAT = "sideslip-pso-state"
_HISTORY_FORMAT = "sideslip-pso-history"
_FORMAT_VERSION = 1


class PsoError(RuntimeError):
    """The optimiser cannot go on: a bad evaluate() reply, a mismatched or unreadable saved
    state, or no finite fitness at all."""


@dataclass(frozen=True)
class Dimension:
    """One searched quantity with its bounds [low, high] (in the searched unit, e.g.
    log10 of the learning rate). ``integer`` dimensions need integral bounds and are
    decoded by rounding (see :mod:`.pso`'s docstring)."""

    name: str
    low: float
    high: float
    integer: bool = False

    def __post_init__(self) -> None:
        if not (math.isfinite(self.low) and math.isfinite(self.high) and self.low < self.high):
            raise ValueError(
                f"dimension {self.name!r}: need finite low < high, got [{self.low}, {self.high}]"
            )
        if self.integer and (self.low != int(self.low) or self.high != int(self.high)):
            raise ValueError(
                f"integer dimension {self.name!r}: bounds must be integers, "
                f"got [{self.low}, {self.high}]"
            )

    def decode(self, position: float) -> float | int:
        """The value evaluated for a position component (rounded half up if integer)."""
        if self.integer:
            return math.floor(position + 0.5)
        return float(position)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "low": self.low, "high": self.high, "integer": self.integer}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Dimension:
        return cls(str(data["name"]), data["low"], data["high"], bool(data.get("integer", False)))


SearchSpace = tuple[Dimension, ...]


def decode(space: SearchSpace, position: Sequence[float]) -> Params:
    """A position vector as the parameters one evaluation gets."""
    return {dim.name: dim.decode(float(x)) for dim, x in zip(space, position, strict=True)}


# --- history -----------------------------------------------------------------------------


@dataclass(frozen=True)
class ParticleRecord:
    """One evaluation: particle ``particle`` at ``iteration``. ``fitness`` is +inf for a
    non-finite or failed evaluation, and then ``error`` says why."""

    iteration: int
    particle: int
    params: Params
    position: tuple[float, ...]
    fitness: float
    error: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {
            "iteration": self.iteration,
            "particle": self.particle,
            "params": dict(self.params),
            "position": list(self.position),
            "fitness": _fitness_to_json(self.fitness),
            "error": self.error,
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> ParticleRecord:
        return cls(
            iteration=int(data["iteration"]),
            particle=int(data["particle"]),
            params=dict(data["params"]),
            position=tuple(float(x) for x in data["position"]),
            fitness=_fitness_from_json(data["fitness"]),
            error=data.get("error"),
        )


@dataclass(frozen=True)
class IterationRecord:
    """One evaluated batch: every particle, the batch's wall time, and the global best
    after it. ``inertia`` is the ω that moved the swarm here (None for iteration 0)."""

    iteration: int
    inertia: float | None
    eval_wall_s: float
    particles: tuple[ParticleRecord, ...]
    best_fitness: float
    best_params: Params
    best_position: tuple[float, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "iteration": self.iteration,
            "inertia": self.inertia,
            "eval_wall_s": self.eval_wall_s,
            "best_fitness": _fitness_to_json(self.best_fitness),
            "best_params": dict(self.best_params),
            "best_position": list(self.best_position),
            "particles": [p.to_dict() for p in self.particles],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> IterationRecord:
        return cls(
            iteration=int(data["iteration"]),
            inertia=None if data["inertia"] is None else float(data["inertia"]),
            eval_wall_s=float(data["eval_wall_s"]),
            particles=tuple(ParticleRecord.from_dict(p) for p in data["particles"]),
            best_fitness=_fitness_from_json(data["best_fitness"]),
            best_params=dict(data["best_params"]),
            best_position=tuple(float(x) for x in data["best_position"]),
        )


@dataclass(frozen=True)
class PsoHistory:
    """Every evaluation of a run, iteration by iteration, with the search space."""

    space: SearchSpace
    iterations: tuple[IterationRecord, ...] = ()

    def appended(self, record: IterationRecord) -> PsoHistory:
        return PsoHistory(self.space, (*self.iterations, record))

    @property
    def particles(self) -> tuple[ParticleRecord, ...]:
        """All evaluations, flat, in order (iteration, then particle)."""
        return tuple(p for it in self.iterations for p in it.particles)

    @property
    def best_fitness_per_iteration(self) -> tuple[float, ...]:
        return tuple(it.best_fitness for it in self.iterations)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": _HISTORY_FORMAT,
            "version": _FORMAT_VERSION,
            "space": [d.to_dict() for d in self.space],
            "iterations": [it.to_dict() for it in self.iterations],
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PsoHistory:
        _check_format(data, _HISTORY_FORMAT)
        return cls(
            space=tuple(Dimension.from_dict(d) for d in data["space"]),
            iterations=tuple(IterationRecord.from_dict(it) for it in data["iterations"]),
        )

    def to_json(self, indent: int | None = 1) -> str:
        """Strict JSON (+inf fitness written as null)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> PsoHistory:
        return cls.from_dict(json.loads(text))


# --- state -------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class PsoState:
    """The swarm after iteration ``iteration`` (0 = the initial swarm evaluated).

    Arrays are read-only, shape (swarm_size, len(space)); ``rng_state`` is the numpy
    ``bit_generator.state`` after the draws of that iteration. Enough to resume.
    """

    settings: PsoSettings
    iteration: int
    positions: np.ndarray
    velocities: np.ndarray
    personal_best_positions: np.ndarray
    personal_best_fitness: np.ndarray
    rng_state: dict[str, Any]
    history: PsoHistory

    def __post_init__(self) -> None:
        for f in ("positions", "velocities", "personal_best_positions", "personal_best_fitness"):
            array = np.array(getattr(self, f), dtype=float)
            array.setflags(write=False)
            object.__setattr__(self, f, array)

    @property
    def space(self) -> SearchSpace:
        return self.history.space

    @property
    def global_best_index(self) -> int:
        """The particle whose personal best is the global best P_g (first on ties)."""
        return int(np.argmin(self.personal_best_fitness))

    @property
    def global_best_position(self) -> np.ndarray:
        return self.personal_best_positions[self.global_best_index]

    @property
    def global_best_fitness(self) -> float:
        return float(self.personal_best_fitness[self.global_best_index])

    @property
    def global_best_params(self) -> Params:
        return decode(self.space, self.global_best_position)

    def to_dict(self) -> dict[str, Any]:
        return {
            "format": _STATE_FORMAT,
            "version": _FORMAT_VERSION,
            "settings": settings_to_dict(self.settings),
            "iteration": self.iteration,
            "positions": self.positions.tolist(),
            "velocities": self.velocities.tolist(),
            "personal_best_positions": self.personal_best_positions.tolist(),
            "personal_best_fitness": [_fitness_to_json(f) for f in self.personal_best_fitness],
            "rng_state": self.rng_state,
            "history": self.history.to_dict(),
        }

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> PsoState:
        _check_format(data, _STATE_FORMAT)
        return cls(
            settings=_settings_from_dict(data["settings"]),
            iteration=int(data["iteration"]),
            positions=np.array(data["positions"], dtype=float),
            velocities=np.array(data["velocities"], dtype=float),
            personal_best_positions=np.array(data["personal_best_positions"], dtype=float),
            personal_best_fitness=np.array(
                [_fitness_from_json(f) for f in data["personal_best_fitness"]], dtype=float
            ),
            rng_state=data["rng_state"],
            history=PsoHistory.from_dict(data["history"]),
        )

    def to_json(self, indent: int | None = None) -> str:
        """Strict JSON (+inf written as null; the generator state's 128-bit ints as ints)."""
        return json.dumps(self.to_dict(), indent=indent, allow_nan=False)

    @classmethod
    def from_json(cls, text: str) -> PsoState:
        return cls.from_dict(json.loads(text))

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the JSON atomically (temp file + rename): a crash mid-write keeps the
        previous checkpoint."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(self.to_json(), encoding="utf-8")
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> PsoState:
        try:
            return cls.from_json(Path(path).read_text(encoding="utf-8"))
        except (KeyError, TypeError, ValueError, PsoError) as exc:
            raise PsoError(f"{path}: not a PSO state ({exc})") from exc


# --- JSON helpers ------------------------------------------------------------------------


def _fitness_to_json(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _fitness_from_json(value: float | None) -> float:
    return math.inf if value is None else float(value)


def settings_to_dict(settings: PsoSettings) -> dict[str, Any]:
    """``settings`` as the plain JSON data a saved :class:`PsoState` holds (tuples as
    lists), so saved and given settings compare equal when they are."""
    return json.loads(json.dumps(asdict(settings)))


def _settings_from_dict(data: Mapping[str, Any]) -> PsoSettings:
    known = {f.name for f in fields(PsoSettings)}
    unknown = set(data) - known
    if unknown:
        raise PsoError(f"unknown PSO settings in saved state: {sorted(unknown)}")
    return PsoSettings(**{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()})


def _check_format(data: Mapping[str, Any], expected: str) -> None:
    if data.get("format") != expected or data.get("version") != _FORMAT_VERSION:
        raise PsoError(
            f"expected format {expected!r} version {_FORMAT_VERSION}, "
            f"got {data.get('format')!r} version {data.get('version')!r}"
        )


__all__ = [
    "Dimension",
    "IterationRecord",
    "Params",
    "ParticleRecord",
    "PsoError",
    "PsoHistory",
    "PsoState",
    "SearchSpace",
    "decode",
    "settings_to_dict",
]
