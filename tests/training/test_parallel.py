"""Swarm evaluators: serial, process pool and Ray agree, keep the swarm's order, and turn a
failing particle into +inf with its error (all failing: an error naming each one)."""

from __future__ import annotations

import importlib
import importlib.util
import math
import sys
import textwrap
from collections.abc import Iterator
from types import ModuleType

import pytest

from sideslip_training.config import PsoSettings
from sideslip_training.parallel import (
    EvaluationError,
    ProcessPoolEvaluator,
    RayEvaluator,
    RayNotInstalledError,
    SerialEvaluator,
    make_evaluator,
)
from sideslip_training.pso import FailedFitness, hyperparameter_space, optimize

# Particle functions must be importable by name in spawned workers: a real module on
# sys.path (spawned children inherit the parent's sys.path).
_PARTICLE_FNS = '''
import os
import time


def quadratic(params, context):
    """sum((p - c)^2) over the context's centre; optionally sleeps params['delay_s']."""
    time.sleep(params.get("delay_s", 0.0))
    return sum((float(params[k]) - c) ** 2 for k, c in context["centre"].items())


def fails_for_negative_x(params, context):
    if params["x"] < 0:
        raise ValueError(f"x = {params['x']} < 0")
    return params["x"] * context["scale"]


def dies_for_negative_x(params, context):
    if params["x"] < 0:
        os._exit(3)
    return params["x"] * context["scale"]
'''


@pytest.fixture(scope="module")
def fns(tmp_path_factory: pytest.TempPathFactory) -> Iterator[ModuleType]:
    folder = tmp_path_factory.mktemp("particle_fns")
    (folder / "sideslip_test_particle_fns.py").write_text(textwrap.dedent(_PARTICLE_FNS))
    sys.path.insert(0, str(folder))
    try:
        yield importlib.import_module("sideslip_test_particle_fns")
    finally:
        sys.path.remove(str(folder))
        sys.modules.pop("sideslip_test_particle_fns", None)


CONTEXT = {"centre": {"x": 0.5, "units": 32}, "scale": 2.0}
SWARM = [{"x": x, "units": u} for x, u in [(0.0, 8), (1.25, 64), (-2.0, 128), (0.5, 32), (3.0, 9)]]
EXPECTED = [0.25 + 24**2, 0.75**2 + 32**2, 2.5**2 + 96**2, 0.0, 2.5**2 + 23**2]


def test_serial_evaluator_computes_each_particle_in_order(fns: ModuleType) -> None:
    assert SerialEvaluator(fns.quadratic, CONTEXT)(SWARM) == pytest.approx(EXPECTED, abs=0)


def test_process_pool_gives_the_serial_values_in_swarm_order(fns: ModuleType) -> None:
    # The first particle finishes last: results must still come back in swarm order.
    swarm = [{**p, "delay_s": 0.3 if i == 0 else 0.0} for i, p in enumerate(SWARM)]
    with ProcessPoolEvaluator(fns.quadratic, CONTEXT, workers=2) as evaluate:
        assert evaluate(swarm) == SerialEvaluator(fns.quadratic, CONTEXT)(swarm)
        assert evaluate(SWARM[:2]) == EXPECTED[:2]  # the pool is reused between batches


@pytest.mark.parametrize("kind", ["serial", "process"])
def test_a_failing_particle_gets_inf_with_its_error_and_the_others_their_values(
    fns: ModuleType, kind: str
) -> None:
    swarm = [{"x": 1.0}, {"x": -1.5}, {"x": 2.0}]
    evaluator = (
        SerialEvaluator(fns.fails_for_negative_x, CONTEXT)
        if kind == "serial"
        else ProcessPoolEvaluator(fns.fails_for_negative_x, CONTEXT, workers=2)
    )
    with evaluator as evaluate:
        values = evaluate(swarm)
    assert values[0] == 2.0 and values[2] == 4.0
    assert isinstance(values[1], FailedFitness) and math.isinf(values[1])
    assert values[1].error == "ValueError: x = -1.5 < 0"


def test_every_particle_failing_raises_naming_each_particle_and_its_params(
    fns: ModuleType,
) -> None:
    with pytest.raises(EvaluationError) as info:
        SerialEvaluator(fns.fails_for_negative_x, CONTEXT)([{"x": -1.0}, {"x": -2.0}])
    message = str(info.value)
    assert "all 2 particles" in message
    assert "particle 0 {'x': -1.0}: ValueError: x = -1.0 < 0" in message
    assert "particle 1 {'x': -2.0}: ValueError: x = -2.0 < 0" in message


def test_a_dead_worker_fails_its_particles_and_the_pool_recovers(fns: ModuleType) -> None:
    with ProcessPoolEvaluator(fns.dies_for_negative_x, CONTEXT, workers=1) as evaluate:
        values = evaluate([{"x": 1.0}, {"x": -1.0}])
        assert values[0] == 2.0
        assert isinstance(values[1], FailedFitness) and "BrokenProcessPool" in values[1].error
        assert evaluate([{"x": 3.0}]) == [6.0]


def test_pso_with_a_process_pool_matches_pso_in_process(fns: ModuleType) -> None:
    space = hyperparameter_space(PsoSettings())
    pso = PsoSettings(swarm_size=4, iterations=2, seed=7)
    context = {"centre": {"log10_learning_rate": -3.0, "hidden_units": 40}}
    serial = optimize(SerialEvaluator(fns.quadratic, context), space, pso)
    with ProcessPoolEvaluator(fns.quadratic, context, workers=2, max_tasks_per_child=2) as ev:
        pooled = optimize(ev, space, pso)
    assert pooled.best_position == serial.best_position
    assert [p.fitness for p in pooled.history.particles] == [
        p.fitness for p in serial.history.particles
    ]


def test_ray_local_instance_gives_the_serial_values_and_failures(fns: ModuleType) -> None:
    ray = pytest.importorskip("ray")
    # Local Ray workers do not see this test's sys.path: ship the module by value.
    ray.cloudpickle.register_pickle_by_value(fns)
    try:
        init = {"num_cpus": 2, "include_dashboard": False, "log_to_driver": False}
        evaluator = RayEvaluator(fns.quadratic, CONTEXT, None, init_kwargs=init)
        with evaluator as evaluate:
            assert ray.is_initialized()
            assert evaluate(SWARM) == SerialEvaluator(fns.quadratic, CONTEXT)(SWARM)
            failing = RayEvaluator(fns.fails_for_negative_x, CONTEXT)  # reuses the instance
            values = failing([{"x": 1.0}, {"x": -1.5}])
            failing.close()  # did not start Ray: leaves it running
            assert ray.is_initialized()
        assert values[0] == 2.0
        assert isinstance(values[1], FailedFitness)
        assert values[1].error == "ValueError: x = -1.5 < 0"
        assert not ray.is_initialized()
    finally:
        ray.cloudpickle.unregister_pickle_by_value(fns)
        if ray.is_initialized():
            ray.shutdown()


def test_make_evaluator_picks_serial_pool_or_ray(fns: ModuleType) -> None:
    serial = make_evaluator(fns.quadratic, CONTEXT, workers=1, ray_address=None)
    pool = make_evaluator(fns.quadratic, CONTEXT, workers=3, ray_address=None)
    assert isinstance(serial, SerialEvaluator)
    assert isinstance(pool, ProcessPoolEvaluator) and pool.workers == 3
    pool.close()
    if importlib.util.find_spec("ray") is not None:
        remote = make_evaluator(fns.quadratic, CONTEXT, workers=1, ray_address="auto")
        assert isinstance(remote, RayEvaluator) and remote.address == "auto"  # not connected


def test_ray_without_ray_installed_says_how_to_install_it(
    fns: ModuleType, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # makes `import ray` raise ImportError
    with pytest.raises(RayNotInstalledError, match=r"install sideslip-training\[ray\]"):
        make_evaluator(fns.quadratic, CONTEXT, workers=1, ray_address="auto")


def test_process_pool_rejects_zero_workers(fns: ModuleType) -> None:
    with pytest.raises(ValueError, match="workers"):
        ProcessPoolEvaluator(fns.quadratic, CONTEXT, workers=0)
