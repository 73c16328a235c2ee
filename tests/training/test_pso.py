"""PSO (paper Eq. 3-4): convergence on known functions, bounds, integers, resume, failures,
history JSON and the convergence plot."""

from __future__ import annotations

import itertools
import json
import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sideslip_training.config import PsoSettings
from sideslip_training.pso import (
    Dimension,
    FailedFitness,
    Params,
    PsoError,
    PsoHistory,
    PsoState,
    SearchSpace,
    decode,
    hyperparameter_space,
    inertia_at,
    optimize,
)
from sideslip_training.pso_plot import plot_convergence


def _box(n: int, low: float, high: float) -> SearchSpace:
    return tuple(Dimension(f"x{i}", low, high) for i in range(n))


def _sphere(optimum: Sequence[float]):
    def evaluate(swarm: list[Params]) -> list[float]:
        return [sum((p[f"x{i}"] - c) ** 2 for i, c in enumerate(optimum)) for p in swarm]

    return evaluate


def _rastrigin(swarm: list[Params]) -> list[float]:
    out = []
    for p in swarm:
        x = np.array(list(p.values()))
        out.append(float(10 * x.size + np.sum(x**2 - 10 * np.cos(2 * np.pi * x))))
    return out


# --- convergence (budgets: swarm_size × (iterations + 1) evaluations) ---------------------


def test_sphere_2d_reaches_the_shifted_optimum() -> None:
    optimum = (1.5, -2.0)
    pso = PsoSettings(swarm_size=20, iterations=60, seed=0)  # 1220 evaluations
    result = optimize(_sphere(optimum), _box(2, -5.0, 5.0), pso)
    assert result.best_fitness < 1e-5
    np.testing.assert_allclose(result.best_position, optimum, atol=1e-2)
    assert result.evaluations == 20 * 61


def test_sphere_5d_reaches_the_shifted_optimum() -> None:
    optimum = (1.5, -2.0, 0.5, 3.0, -1.0)
    pso = PsoSettings(swarm_size=30, iterations=100, seed=0)  # 3030 evaluations
    result = optimize(_sphere(optimum), _box(5, -5.0, 5.0), pso)
    assert result.best_fitness < 1e-4
    np.testing.assert_allclose(result.best_position, optimum, atol=2e-2)


def test_rastrigin_2d_finds_the_global_minimum_among_local_ones() -> None:
    pso = PsoSettings(swarm_size=30, iterations=100, seed=0)  # 3030 evaluations
    result = optimize(_rastrigin, _box(2, -5.12, 5.12), pso)
    # The nearest local minima (|x| ≈ 1) have fitness ≈ 1; the global one is 0 at 0.
    assert result.best_fitness < 1e-4
    np.testing.assert_allclose(result.best_position, (0.0, 0.0), atol=1e-2)


def test_global_best_never_gets_worse_and_is_the_best_seen() -> None:
    result = optimize(_rastrigin, _box(2, -5.12, 5.12), PsoSettings(swarm_size=6, iterations=8))
    bests = result.history.best_fitness_per_iteration
    assert all(b2 <= b1 for b1, b2 in itertools.pairwise(bests))
    assert result.best_fitness == min(p.fitness for p in result.history.particles)


# --- iterations, inertia, integers --------------------------------------------------------


def test_evaluate_is_called_once_per_iteration_plus_the_initial_swarm() -> None:
    sizes: list[int] = []

    def evaluate(swarm: list[Params]) -> list[float]:
        sizes.append(len(swarm))
        return [abs(p["x0"]) for p in swarm]

    result = optimize(evaluate, _box(1, -1, 1), PsoSettings(swarm_size=4, iterations=3))
    assert sizes == [4, 4, 4, 4]
    assert [it.iteration for it in result.history.iterations] == [0, 1, 2, 3]
    assert result.state.iteration == 3


def test_inertia_decreases_linearly_from_start_to_end() -> None:
    pso = PsoSettings(iterations=5, inertia_start=0.9, inertia_end=0.4)
    assert [inertia_at(m, pso) for m in range(1, 6)] == pytest.approx(
        [0.9, 0.775, 0.65, 0.525, 0.4]
    )
    history = optimize(_rastrigin, _box(1, -1, 1), replace(pso, swarm_size=2)).history
    assert history.iterations[0].inertia is None
    assert [it.inertia for it in history.iterations[1:]] == pytest.approx(
        [0.9, 0.775, 0.65, 0.525, 0.4]
    )


def test_integer_dimension_is_evaluated_as_integers_within_bounds() -> None:
    space = hyperparameter_space(PsoSettings())
    assert [d.name for d in space] == ["log10_learning_rate", "hidden_units"]
    seen: list[Params] = []

    def evaluate(swarm: list[Params]) -> list[float]:
        seen.extend(swarm)
        # best at lr = 10**-2.5, 37 hidden units
        return [
            (p["log10_learning_rate"] + 2.5) ** 2 + (p["hidden_units"] - 37) ** 2 for p in swarm
        ]

    result = optimize(evaluate, space, PsoSettings(swarm_size=8, iterations=15))
    assert all(type(p["hidden_units"]) is int and 8 <= p["hidden_units"] <= 128 for p in seen)
    assert all(type(p["log10_learning_rate"]) is float for p in seen)
    assert result.best_params["hidden_units"] == 37
    assert type(result.best_params["hidden_units"]) is int


def test_integer_decoding_rounds_half_up() -> None:
    dim = Dimension("units", 8, 128, integer=True)
    assert [dim.decode(x) for x in (8.0, 8.49, 8.5, 127.5, 128.0)] == [8, 8, 9, 128, 128]
    with pytest.raises(ValueError, match="integers"):
        Dimension("units", 8.5, 128, integer=True)
    with pytest.raises(ValueError, match="low < high"):
        Dimension("x", 1.0, 1.0)


# --- clamp invariants (hypothesis over bounds, seeds and swarm sizes) ---------------------


@settings(max_examples=150, deadline=None)
@given(
    lows=st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=3),
    widths=st.lists(st.floats(1e-3, 1e3), min_size=3, max_size=3),
    integer=st.lists(st.booleans(), min_size=3, max_size=3),
    slopes=st.lists(st.floats(-10, 10), min_size=3, max_size=3),
    seed=st.integers(0, 2**32 - 1),
    swarm_size=st.integers(1, 6),
    iterations=st.integers(0, 6),
    velocity_fraction=st.floats(0.01, 1.0),
)
def test_positions_stay_in_bounds_and_velocities_within_vmax(
    lows: list[float],
    widths: list[float],
    integer: list[bool],
    slopes: list[float],
    seed: int,
    swarm_size: int,
    iterations: int,
    velocity_fraction: float,
) -> None:
    space = tuple(
        Dimension(f"x{i}", math.floor(lo), math.floor(lo) + max(1, round(w)), True)
        if integer[i]
        else Dimension(f"x{i}", lo, lo + w)
        for i, (lo, w) in enumerate(zip(lows, widths, strict=False))
    )
    low = np.array([d.low for d in space])
    high = np.array([d.high for d in space])
    v_max = velocity_fraction * (high - low)
    pso = PsoSettings(
        swarm_size=swarm_size,
        iterations=iterations,
        seed=seed,
        velocity_fraction=velocity_fraction,
    )

    def evaluate(swarm: list[Params]) -> list[float]:
        # A linear fitness: its minimum is a corner, so the swarm presses on the bounds.
        for p in swarm:
            for d in space:
                assert d.low <= p[d.name] <= d.high
                assert type(p[d.name]) is (int if d.integer else float)
        return [sum(s * p[d.name] for s, d in zip(slopes, space, strict=False)) for p in swarm]

    states: list[PsoState] = []
    optimize(evaluate, space, pso, on_iteration=states.append)
    assert [s.iteration for s in states] == list(range(iterations + 1))
    for state in states:
        assert np.all(state.positions >= low) and np.all(state.positions <= high)
        assert np.all(np.abs(state.velocities) <= v_max)
        assert np.all(state.personal_best_positions >= low)
        assert np.all(state.personal_best_positions <= high)


def test_a_component_clamped_to_its_bound_loses_its_velocity() -> None:
    # Minimum on the lower bound: particles overshoot it, are put on it and stop there
    # (without the zeroing, inertia would keep an outward velocity ω^k v ≠ 0).
    space = (Dimension("x", 0.0, 1.0), Dimension("y", -1.0, 1.0))
    pso = PsoSettings(swarm_size=5, iterations=30, velocity_fraction=0.5, seed=1)
    states: list[PsoState] = []
    optimize(lambda s: [p["x"] + p["y"] ** 2 for p in s], space, pso, on_iteration=states.append)
    on_bound = [(st.positions[:, 0] == 0.0, st.velocities[:, 0]) for st in states[1:]]
    assert sum(at.sum() for at, _ in on_bound[-5:]) >= 5 * 4, "the swarm should reach the bound"
    for at, velocity in on_bound:
        np.testing.assert_array_equal(velocity[at], 0.0)


# --- resume -------------------------------------------------------------------------------


class _Interrupted(Exception):
    pass


@pytest.mark.parametrize("stop_after", [0, 3, 7])
def test_resuming_a_saved_state_gives_the_uninterrupted_result(
    stop_after: int, tmp_path: Path
) -> None:
    space = (Dimension("a", -5.12, 5.12), Dimension("units", 8, 128, integer=True))

    def evaluate(swarm: list[Params]) -> list[float]:
        return _rastrigin([{"a": p["a"], "u": (p["units"] - 60) / 20} for p in swarm])

    pso = PsoSettings(swarm_size=5, iterations=8, seed=42)
    full = optimize(evaluate, space, pso)

    checkpoint = tmp_path / "pso_state.json"

    def save_then_stop(state: PsoState) -> None:
        state.save(checkpoint)
        if state.iteration == stop_after:
            raise _Interrupted

    with pytest.raises(_Interrupted):
        optimize(evaluate, space, pso, on_iteration=save_then_stop)
    saved = PsoState.load(checkpoint)
    assert saved.iteration == stop_after
    calls: list[int] = []

    def counting(swarm: list[Params]) -> list[float]:
        calls.append(len(swarm))
        return evaluate(swarm)

    resumed = optimize(counting, space, pso, state=saved)
    assert len(calls) == pso.iterations - stop_after
    assert resumed.best_position == full.best_position
    assert resumed.best_fitness == full.best_fitness
    assert resumed.best_params == full.best_params
    np.testing.assert_array_equal(resumed.state.positions, full.state.positions)
    np.testing.assert_array_equal(resumed.state.velocities, full.state.velocities)
    assert resumed.state.rng_state == full.state.rng_state
    for a, b in zip(resumed.history.particles, full.history.particles, strict=True):
        assert (a.iteration, a.particle, a.params, a.position, a.fitness) == (
            b.iteration,
            b.particle,
            b.params,
            b.position,
            b.fitness,
        )


def test_resuming_with_other_settings_or_space_is_refused() -> None:
    space = _box(2, -1, 1)
    pso = PsoSettings(swarm_size=3, iterations=2)
    state = optimize(_rastrigin, space, pso).state
    with pytest.raises(PsoError, match="seed"):
        optimize(_rastrigin, space, replace(pso, seed=1), state=state)
    with pytest.raises(PsoError, match="searches"):
        optimize(_rastrigin, _box(2, -2, 2), pso, state=state)


def test_a_completed_state_resumes_to_its_result_without_evaluating() -> None:
    space, pso = _box(2, -1, 1), PsoSettings(swarm_size=3, iterations=2)
    done = optimize(_rastrigin, space, pso)

    def never(swarm: list[Params]) -> list[float]:
        raise AssertionError("evaluated again")

    again = optimize(never, space, pso, state=PsoState.from_json(done.state.to_json()))
    assert again.best_position == done.best_position


# --- non-finite fitness and failures ------------------------------------------------------


def test_non_finite_fitness_counts_as_inf_and_never_becomes_a_best() -> None:
    space = _box(1, -1.0, 1.0)

    def evaluate(swarm: list[Params]) -> list[float]:
        # "Diverges" (NaN, then -inf) for x < 0, which would otherwise be the better half.
        out: list[float] = []
        for p in swarm:
            x = p["x0"]
            out.append(x if x >= 0 else (math.nan if x < -0.5 else -math.inf))
        return out

    result = optimize(evaluate, space, PsoSettings(swarm_size=6, iterations=5, seed=3))
    bad = [p for p in result.history.particles if p.position[0] < 0]
    assert bad, "the seed should put some particles at x < 0"
    assert all(p.fitness == math.inf and "non-finite" in (p.error or "") for p in bad)
    assert result.best_position[0] >= 0 and math.isfinite(result.best_fitness)
    assert all(math.isfinite(it.best_fitness) for it in result.history.iterations)


def test_failed_fitness_is_inf_and_its_error_is_kept_in_the_history() -> None:
    def evaluate(swarm: list[Params]) -> list[float]:
        return [
            FailedFitness("RuntimeError: CUDA OOM") if i == 0 else abs(p["x0"])
            for i, p in enumerate(swarm)
        ]

    result = optimize(evaluate, _box(1, -1, 1), PsoSettings(swarm_size=3, iterations=1))
    first = [p for p in result.history.particles if p.particle == 0]
    assert all(p.fitness == math.inf and p.error == "RuntimeError: CUDA OOM" for p in first)
    assert result.state.global_best_index != 0


def test_no_finite_fitness_at_all_is_an_error() -> None:
    with pytest.raises(PsoError, match="no particle gave a finite fitness"):
        optimize(lambda s: [math.nan] * len(s), _box(1, 0, 1), PsoSettings(swarm_size=2))


def test_a_wrong_number_of_fitness_values_is_an_error() -> None:
    with pytest.raises(PsoError, match="1 fitness values for 2 particles"):
        optimize(lambda s: [0.0], _box(1, 0, 1), PsoSettings(swarm_size=2))


# --- JSON and plot ------------------------------------------------------------------------


def _run_with_failures() -> tuple[SearchSpace, PsoHistory, PsoState]:
    space = hyperparameter_space(PsoSettings())

    def evaluate(swarm: list[Params]) -> list[float]:
        return [
            math.nan if p["hidden_units"] > 100 else 0.1 + abs(p["log10_learning_rate"] + 3)
            for p in swarm
        ]

    result = optimize(evaluate, space, PsoSettings(swarm_size=6, iterations=4, seed=5))
    return space, result.history, result.state


def test_history_and_state_round_trip_through_strict_json() -> None:
    space, history, state = _run_with_failures()
    assert any(p.fitness == math.inf for p in history.particles)
    text = history.to_json()
    json.loads(text, parse_constant=lambda c: pytest.fail(f"non-strict JSON constant {c}"))
    assert PsoHistory.from_json(text) == history

    back = PsoState.from_json(state.to_json())
    assert back.history == state.history and back.space == space
    assert back.settings == state.settings and back.rng_state == state.rng_state
    for name in ("positions", "velocities", "personal_best_positions", "personal_best_fitness"):
        np.testing.assert_array_equal(getattr(back, name), getattr(state, name))
    assert decode(space, back.global_best_position) == state.global_best_params


def test_convergence_plot_renders_a_png(tmp_path: Path) -> None:
    _, history, _ = _run_with_failures()
    out = plot_convergence(history, tmp_path / "pso.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert out.stat().st_size > 10_000


def test_loading_a_file_that_is_not_a_pso_state_names_the_file(tmp_path: Path) -> None:
    path = tmp_path / "pso_state.json"
    path.write_text(json.dumps({"format": "something-else", "version": 1}))
    with pytest.raises(PsoError, match=r"pso_state\.json: not a PSO state"):
        PsoState.load(path)
