"""Swarm evaluators: run one fitness function per particle, serially, on local processes
or on a Ray cluster.

Every evaluator is a callable ``evaluate(swarm) -> list[float]`` (what
:func:`sideslip_training.pso.optimize` expects) built from a picklable top-level function
``fn(params, context) -> float``. ``context`` is what every particle shares (datasets,
profile, device): it is sent once per worker process (process pool) or stored once in
the object store (Ray), not once per particle.

Failure policy, the same for all evaluators: an exception in one particle is logged with
its traceback and that particle gets :class:`~sideslip_training.pso.FailedFitness` (+inf,
the error kept in the PSO history), so one bad training does not end a multi-hour search.
When *every* particle of a batch fails, the cause is almost certainly not the
hyper-parameters (a missing import on the workers, a wrong device, a bad dataset path), and
:class:`EvaluationError` is raised naming each particle, its parameters and its error.
``KeyboardInterrupt`` is never caught.

Results always come back in the order of the swarm.
"""

from __future__ import annotations

import concurrent.futures
import logging
import multiprocessing
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures.process import BrokenProcessPool
from types import TracebackType
from typing import Any, Protocol, Self

from sideslip_training.pso import FailedFitness

ParticleFn = Callable[[dict[str, Any], Any], float]
"""``fn(params, context) -> fitness``; top-level (picklable by reference)."""

RAY_INSTALL_HINT = "install sideslip-training[ray] (pip install 'sideslip-training[ray]')"

_log = logging.getLogger(__name__)


class EvaluationError(RuntimeError):
    """Every particle of a batch failed; the message lists them."""


class RayNotInstalledError(ImportError):
    """Ray was asked for but is not importable."""


class Evaluator(Protocol):
    """What :func:`make_evaluator` returns: ``evaluate(swarm)`` plus ``close()``; also a
    context manager that closes on exit."""

    def __call__(self, swarm: Sequence[Mapping[str, Any]]) -> list[float]: ...

    def close(self) -> None: ...

    def __enter__(self) -> Self: ...

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None: ...


class _Closing:
    def close(self) -> None:
        """Release workers (no-op for the serial evaluator)."""

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


class SerialEvaluator(_Closing):
    """Particles one after the other in this process."""

    def __init__(self, fn: ParticleFn, context: Any) -> None:
        self.fn = fn
        self.context = context

    def __call__(self, swarm: Sequence[Mapping[str, Any]]) -> list[float]:
        results: list[float] = []
        for i, params in enumerate(swarm):
            try:
                results.append(float(self.fn(dict(params), self.context)))
            except Exception as exc:
                results.append(_failure(i, params, exc))
        return _checked(swarm, results)


class ProcessPoolEvaluator(_Closing):
    """Particles on ``workers`` local processes (``concurrent.futures``, "spawn" start
    method: forking a process that has initialised torch or CUDA is unsafe).

    ``fn`` and ``context`` go to each worker once, when it starts. The pool starts on the
    first call and is kept between calls (no re-import of torch per batch);
    ``max_tasks_per_child=1`` instead gives every particle a fresh process (memory that a
    training leaks is returned, at the cost of one interpreter start per particle). A
    worker that dies (killed for memory, a segfault) fails the particles still running;
    the pool is rebuilt for the next batch.
    """

    def __init__(
        self,
        fn: ParticleFn,
        context: Any,
        workers: int,
        *,
        max_tasks_per_child: int | None = None,
    ) -> None:
        if workers < 1:
            raise ValueError(f"workers must be >= 1, got {workers}")
        self.fn = fn
        self.context = context
        self.workers = workers
        self.max_tasks_per_child = max_tasks_per_child
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None

    def _executor(self) -> concurrent.futures.ProcessPoolExecutor:
        if self._pool is None:
            self._pool = concurrent.futures.ProcessPoolExecutor(
                max_workers=self.workers,
                mp_context=multiprocessing.get_context("spawn"),
                initializer=_init_worker,
                initargs=(self.fn, self.context),
                max_tasks_per_child=self.max_tasks_per_child,
            )
        return self._pool

    def __call__(self, swarm: Sequence[Mapping[str, Any]]) -> list[float]:
        pool = self._executor()
        futures = [pool.submit(_run_in_worker, dict(params)) for params in swarm]
        results: list[float] = []
        broken = False
        for i, (params, future) in enumerate(zip(swarm, futures, strict=True)):
            try:
                results.append(float(future.result()))
            except BrokenProcessPool as exc:
                broken = True
                results.append(_failure(i, params, exc))
            except Exception as exc:
                results.append(_failure(i, params, exc))
        if broken:
            self.close()
        return _checked(swarm, results)

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


class RayEvaluator(_Closing):
    """Particles as Ray tasks, on an existing cluster (``address="auto"`` on a cluster
    node, ``"ray://head:10001"`` through Ray Client) or on a local instance started here
    (``address=None``).

    Each task reserves ``num_cpus_per_task`` CPUs and ``num_gpus_per_task`` GPUs (a
    fraction such as 0.5 packs two trainings on one GPU). ``context`` is put in the object
    store once per evaluator. Ray connects on the first call (or on ``start()``/``with``);
    ``close()`` disconnects only if this evaluator initialised Ray. ``init_kwargs`` go to
    ``ray.init`` (e.g. ``num_cpus`` for a local instance). Every node must be able to
    import ``fn``'s module (sideslip-training installed there). Ray's own retry of tasks
    whose worker died applies (``max_retries``; exceptions from ``fn`` are not retried).
    """

    def __init__(
        self,
        fn: ParticleFn,
        context: Any,
        address: str | None = None,
        *,
        num_cpus_per_task: float = 1,
        num_gpus_per_task: float = 0,
        max_retries: int = 3,
        init_kwargs: Mapping[str, Any] | None = None,
    ) -> None:
        self._ray = import_ray()
        self.fn = fn
        self.context = context
        self.address = address
        self.num_cpus_per_task = num_cpus_per_task
        self.num_gpus_per_task = num_gpus_per_task
        self.max_retries = max_retries
        self.init_kwargs = dict(init_kwargs or {})
        self._owns_ray = False
        self._refs: tuple[Any, Any] | None = None
        self._task: Any = None

    def start(self) -> None:
        """Connect (or start a local Ray) and upload ``fn`` and ``context``; idempotent."""
        if self._refs is not None:
            return
        ray = self._ray
        if not ray.is_initialized():
            ray.init(address=self.address, **self.init_kwargs)
            self._owns_ray = True
        self._refs = (ray.put(self.fn), ray.put(self.context))
        self._task = ray.remote(
            num_cpus=self.num_cpus_per_task,
            num_gpus=self.num_gpus_per_task,
            max_retries=self.max_retries,
        )(_run_particle)

    def __enter__(self) -> Self:
        self.start()
        return self

    def __call__(self, swarm: Sequence[Mapping[str, Any]]) -> list[float]:
        self.start()
        assert self._refs is not None
        fn_ref, context_ref = self._refs
        pending = [self._task.remote(fn_ref, dict(params), context_ref) for params in swarm]
        results: list[float] = []
        for i, (params, ref) in enumerate(zip(swarm, pending, strict=True)):
            try:
                results.append(float(self._ray.get(ref)))
            except Exception as exc:
                # RayTaskError wraps fn's exception (.cause); other RayErrors are the
                # cluster's (worker died, node lost).
                results.append(_failure(i, params, getattr(exc, "cause", None) or exc))
        return _checked(swarm, results)

    def close(self) -> None:
        self._refs = None
        self._task = None
        if self._owns_ray:
            self._ray.shutdown()
            self._owns_ray = False


def make_evaluator(
    fn: ParticleFn,
    context: Any,
    *,
    workers: int,
    ray_address: str | None,
    num_gpus_per_task: float = 0,
) -> Evaluator:
    """The evaluator a CLI asks for: Ray at ``ray_address`` when given (``"auto"`` or
    ``"ray://..."``), else a process pool of ``workers`` processes, else (``workers <= 1``)
    the serial evaluator in this process. Raises :class:`RayNotInstalledError` at once if
    Ray is asked for but not installed."""
    if ray_address is not None:
        return RayEvaluator(fn, context, ray_address, num_gpus_per_task=num_gpus_per_task)
    if workers > 1:
        return ProcessPoolEvaluator(fn, context, workers)
    return SerialEvaluator(fn, context)


def import_ray() -> Any:
    """``import ray``, or :class:`RayNotInstalledError` saying how to install it."""
    try:
        import ray
    except ImportError as exc:
        raise RayNotInstalledError(f"Ray is not installed: {RAY_INSTALL_HINT}") from exc
    return ray


# --- worker side -------------------------------------------------------------------------

_worker_fn: ParticleFn | None = None
_worker_context: Any = None


def _init_worker(fn: ParticleFn, context: Any) -> None:
    global _worker_fn, _worker_context
    _worker_fn, _worker_context = fn, context


def _run_in_worker(params: dict[str, Any]) -> float:
    assert _worker_fn is not None, "worker not initialised"
    return float(_worker_fn(params, _worker_context))


def _run_particle(fn: ParticleFn, params: dict[str, Any], context: Any) -> float:
    return float(fn(params, context))


# --- failure policy ----------------------------------------------------------------------


def _failure(index: int, params: Mapping[str, Any], exc: BaseException) -> FailedFitness:
    _log.warning("particle %d %s failed", index, dict(params), exc_info=exc)
    return FailedFitness(f"{type(exc).__name__}: {exc}")


def _checked(swarm: Sequence[Mapping[str, Any]], results: list[float]) -> list[float]:
    failures = [(i, r) for i, r in enumerate(results) if isinstance(r, FailedFitness)]
    if results and len(failures) == len(results):
        lines = "\n".join(f"  particle {i} {dict(swarm[i])}: {r.error}" for i, r in failures)
        raise EvaluationError(f"all {len(results)} particles of the batch failed:\n{lines}")
    return results


__all__ = [
    "RAY_INSTALL_HINT",
    "EvaluationError",
    "Evaluator",
    "ParticleFn",
    "ProcessPoolEvaluator",
    "RayEvaluator",
    "RayNotInstalledError",
    "SerialEvaluator",
    "import_ray",
    "make_evaluator",
]
