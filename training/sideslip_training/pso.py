"""Particle-swarm optimisation (paper section 2.2, Eq. 3-4): a pure numpy core.

The swarm minimises a fitness (for us: the validation MAE of one training per particle)
over a box-bounded search space. Each particle i has a position X_i and a velocity V_i;
after every evaluation its personal best P_i and the swarm's global best P_g are updated,
and the next move is

    V_id ← ω V_id + c1 r1 (P_id − X_id) + c2 r2 (P_gd − X_id)      (Eq. 3)
    X_id ← X_id + V_id                                             (Eq. 4)

with r1, r2 ~ U(0, 1) drawn afresh per particle and per dimension.

Choices the paper leaves open (documented here, the one place they are made):

- **Iterations.** Iteration 0 evaluates the initial swarm: positions uniform in the
  bounds, velocities uniform in [−Vmax, Vmax]. Iterations 1..``settings.iterations``
  each move the whole swarm by Eq. 3-4 and evaluate it again. The number of fitness
  evaluations (trainings) is therefore ``swarm_size × (iterations + 1)``; the paper
  profile (8 particles, 10 iterations) trains 88 networks.
- **Synchronous swarm.** The whole swarm moves, then is evaluated as one batch (so the
  batch can run in parallel); P_g is the best after the previous batch.
- **Inertia ω** decreases linearly from ``inertia_start`` (iteration 1) to
  ``inertia_end`` (the last iteration); the paper only says "inertia factor".
- **Clamps.** Vmax = ``velocity_fraction`` × (high − low) per dimension, applied to the
  velocity of Eq. 3. The paper's [−Xmax, Xmax] becomes each dimension's [low, high]:
  a component that would leave the box is put on the bound and its velocity set to
  zero, so the particle does not keep pushing against the wall.
- **Integer dimensions** (hidden units) are searched as continuous values in
  [low, high] and rounded half up when decoded for evaluation. The two end values
  therefore get half the basin of the inner ones; the swarm's dynamics stay smooth.
- **Non-finite fitness** (a diverged training: NaN or ±inf MAE) and failed evaluations
  (see :class:`FailedFitness`) count as +inf: they never become a personal or global
  best, and the reason is kept in the history.
- **Ties** keep the older best (strict ``<``); the global best is the first particle
  with the lowest personal-best fitness.

:class:`PsoState` holds everything needed to continue after an interruption (including
the random generator's state), so a resumed run ends exactly where an uninterrupted one
would, given a deterministic fitness. It and the other JSON records (the search space's
:class:`Dimension`, :class:`PsoHistory`, ...) live in :mod:`.pso_records`; this module
re-exports them, so callers may import every PSO name from here.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from sideslip_training.config import PsoSettings
from sideslip_training.pso_records import (
    Dimension,
    IterationRecord,
    Params,
    ParticleRecord,
    PsoError,
    PsoHistory,
    PsoState,
    SearchSpace,
    decode,
    settings_to_dict,
)

EvaluateFn = Callable[[list[Params]], Sequence[float]]
"""Evaluates a whole swarm; returns one fitness per particle, in order (lower is better)."""


class FailedFitness(float):
    """+inf with the reason attached: what an evaluator returns for a particle whose
    evaluation raised, so one bad particle does not end a multi-hour search.

    It is a ``float`` (``math.isinf(FailedFitness("..."))`` holds), so evaluators keep the
    plain ``list[float]`` contract; :func:`optimize` copies ``error`` into the history.
    """

    __slots__ = ("error",)
    error: str

    def __new__(cls, error: str) -> FailedFitness:
        obj = super().__new__(cls, math.inf)
        obj.error = error
        return obj

    def __reduce__(self) -> tuple[type[FailedFitness], tuple[str]]:
        return (FailedFitness, (self.error,))

    def __repr__(self) -> str:
        return f"FailedFitness({self.error!r})"


def hyperparameter_space(settings: PsoSettings) -> SearchSpace:
    """The paper's search space: log10 learning rate and hidden units, bounds from
    ``settings``."""
    lr_low, lr_high = settings.log10_lr_bounds
    hidden_low, hidden_high = settings.hidden_bounds
    return (
        Dimension("log10_learning_rate", float(lr_low), float(lr_high)),
        Dimension("hidden_units", hidden_low, hidden_high, integer=True),
    )


@dataclass(frozen=True, eq=False)
class PsoResult:
    """The global best after the last iteration, the full history and the final state."""

    best_params: Params
    best_position: tuple[float, ...]
    best_fitness: float
    history: PsoHistory
    state: PsoState

    @property
    def evaluations(self) -> int:
        return len(self.history.particles)


# --- the optimiser -----------------------------------------------------------------------


def inertia_at(iteration: int, settings: PsoSettings) -> float:
    """ω used to move the swarm into ``iteration`` (1..settings.iterations): linear from
    ``inertia_start`` at iteration 1 to ``inertia_end`` at the last one."""
    if settings.iterations <= 1:
        return settings.inertia_start
    fraction = (iteration - 1) / (settings.iterations - 1)
    return settings.inertia_start + (settings.inertia_end - settings.inertia_start) * fraction


def optimize(
    evaluate: EvaluateFn,
    space: SearchSpace,
    settings: PsoSettings,
    *,
    state: PsoState | None = None,
    on_iteration: Callable[[PsoState], None] | None = None,
) -> PsoResult:
    """Minimise ``evaluate`` over ``space`` with PSO (Eq. 3-4; choices in the module doc).

    ``evaluate`` gets the whole swarm decoded (``settings.swarm_size`` dicts) and returns
    one fitness per particle in the same order; it is called ``settings.iterations + 1``
    times, so there are ``swarm_size × (iterations + 1)`` evaluations in all. NaN/±inf and
    :class:`FailedFitness` count as +inf.

    ``on_iteration(state)`` runs after every completed iteration, the initial one
    included; save ``state`` there (``state.save(path)``) and pass it back as ``state``
    to resume: only the iterations after ``state.iteration`` are evaluated, and the result
    is the one an uninterrupted run gives (for a deterministic ``evaluate``).

    Raises PsoError for a mismatched ``state``, a wrong number of fitness values, or when
    no evaluation at all gave a finite fitness.
    """
    space = tuple(space)
    _validate(space, settings)
    low = np.array([d.low for d in space], dtype=float)
    high = np.array([d.high for d in space], dtype=float)
    v_max = settings.velocity_fraction * (high - low)
    n, n_dims = settings.swarm_size, len(space)
    rng = np.random.default_rng(settings.seed)

    if state is None:
        positions = rng.uniform(low, high, size=(n, n_dims))
        velocities = rng.uniform(-v_max, v_max, size=(n, n_dims))
        batch = _evaluate_swarm(evaluate, space, positions, iteration=0, inertia=None)
        state = _next_state(settings, batch, positions, velocities, rng, previous=None, space=space)
        if on_iteration is not None:
            on_iteration(state)
    else:
        _check_resumable(state, space, settings)
        rng.bit_generator.state = state.rng_state

    while state.iteration < settings.iterations:
        iteration = state.iteration + 1
        inertia = inertia_at(iteration, settings)
        x = np.array(state.positions)
        r1 = rng.random((n, n_dims))
        r2 = rng.random((n, n_dims))
        velocities = (
            inertia * state.velocities
            + settings.c1 * r1 * (state.personal_best_positions - x)
            + settings.c2 * r2 * (state.global_best_position - x)
        )
        velocities = np.clip(velocities, -v_max, v_max)
        positions = x + velocities
        outside = (positions < low) | (positions > high)
        positions = np.clip(positions, low, high)
        velocities[outside] = 0.0
        batch = _evaluate_swarm(evaluate, space, positions, iteration, inertia)
        state = _next_state(
            settings, batch, positions, velocities, rng, previous=state, space=space
        )
        if on_iteration is not None:
            on_iteration(state)

    if not math.isfinite(state.global_best_fitness):
        raise PsoError(
            f"no particle gave a finite fitness in {len(state.history.particles)} evaluations; "
            f"first error: {state.history.particles[0].error}"
        )
    return PsoResult(
        best_params=state.global_best_params,
        best_position=tuple(float(x) for x in state.global_best_position),
        best_fitness=state.global_best_fitness,
        history=state.history,
        state=state,
    )


@dataclass(frozen=True, eq=False)
class _Batch:
    """One evaluated swarm, before the bests are updated."""

    iteration: int
    inertia: float | None
    wall_s: float
    fitness: np.ndarray
    particles: tuple[ParticleRecord, ...]


def _evaluate_swarm(
    evaluate: EvaluateFn,
    space: SearchSpace,
    positions: np.ndarray,
    iteration: int,
    inertia: float | None,
) -> _Batch:
    swarm = [decode(space, p) for p in positions]
    start = time.perf_counter()
    replies = list(evaluate([dict(p) for p in swarm]))
    wall_s = time.perf_counter() - start
    if len(replies) != len(swarm):
        raise PsoError(
            f"iteration {iteration}: evaluate returned {len(replies)} fitness values "
            f"for {len(swarm)} particles"
        )
    fitness = np.empty(len(swarm))
    records = []
    for i, (params, reply) in enumerate(zip(swarm, replies, strict=True)):
        error = getattr(reply, "error", None)
        try:
            value = float(reply)
        except (TypeError, ValueError):
            raise PsoError(
                f"iteration {iteration}: evaluate returned {reply!r} for particle {i} {params}, "
                "not a number"
            ) from None
        if not math.isfinite(value):
            error = error or f"non-finite fitness {value!r}"
            value = math.inf
        fitness[i] = value
        records.append(
            ParticleRecord(
                iteration=iteration,
                particle=i,
                params=params,
                position=tuple(float(x) for x in positions[i]),
                fitness=value,
                error=error,
            )
        )
    return _Batch(iteration, inertia, wall_s, fitness, tuple(records))


def _next_state(
    settings: PsoSettings,
    batch: _Batch,
    positions: np.ndarray,
    velocities: np.ndarray,
    rng: np.random.Generator,
    *,
    previous: PsoState | None,
    space: SearchSpace,
) -> PsoState:
    """Personal and global bests updated with ``batch`` (strict improvement only)."""
    fitness = batch.fitness
    history = PsoHistory(space) if previous is None else previous.history
    if previous is None:
        best_positions, best_fitness = positions.copy(), fitness.copy()
    else:
        improved = fitness < previous.personal_best_fitness
        best_positions = np.where(improved[:, None], positions, previous.personal_best_positions)
        best_fitness = np.where(improved, fitness, previous.personal_best_fitness)
    g = int(np.argmin(best_fitness))
    iteration_record = IterationRecord(
        iteration=batch.iteration,
        inertia=batch.inertia,
        eval_wall_s=batch.wall_s,
        particles=batch.particles,
        best_fitness=float(best_fitness[g]),
        best_params=decode(space, best_positions[g]),
        best_position=tuple(float(x) for x in best_positions[g]),
    )
    return PsoState(
        settings=settings,
        iteration=batch.iteration,
        positions=positions,
        velocities=velocities,
        personal_best_positions=best_positions,
        personal_best_fitness=best_fitness,
        rng_state=rng.bit_generator.state,
        history=history.appended(iteration_record),
    )


def _validate(space: SearchSpace, settings: PsoSettings) -> None:
    if not space:
        raise ValueError("empty search space")
    names = [d.name for d in space]
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate dimension names in {names}")
    if settings.swarm_size < 1:
        raise ValueError(f"swarm_size must be >= 1, got {settings.swarm_size}")
    if settings.iterations < 0:
        raise ValueError(f"iterations must be >= 0, got {settings.iterations}")
    if not settings.velocity_fraction > 0:
        raise ValueError(f"velocity_fraction must be > 0, got {settings.velocity_fraction}")
    if settings.c1 < 0 or settings.c2 < 0:
        raise ValueError(f"c1, c2 must be >= 0, got {settings.c1}, {settings.c2}")


def _check_resumable(state: PsoState, space: SearchSpace, settings: PsoSettings) -> None:
    if state.space != space:
        raise PsoError(f"saved state searches {state.space}, not {space}")
    saved, given = settings_to_dict(state.settings), settings_to_dict(settings)
    if saved != given:
        diff = {k: (saved[k], given[k]) for k in saved if saved[k] != given[k]}
        raise PsoError(f"saved state was run with other PSO settings (saved, given): {diff}")
    if state.iteration > settings.iterations:
        raise PsoError(f"saved state is at iteration {state.iteration} > {settings.iterations}")
    expected = (settings.swarm_size, len(space))
    if state.positions.shape != expected:
        raise PsoError(f"saved swarm has shape {state.positions.shape}, expected {expected}")


__all__ = [
    "Dimension",
    "EvaluateFn",
    "FailedFitness",
    "IterationRecord",
    "Params",
    "ParticleRecord",
    "PsoError",
    "PsoHistory",
    "PsoResult",
    "PsoState",
    "SearchSpace",
    "decode",
    "hyperparameter_space",
    "inertia_at",
    "optimize",
]
