"""Shared fixtures for the multi-process ROS 2 tests (helpers live in ros_support.py).

Every ROS test gets its own DDS domain (``ros_domain``), limited to loopback, so tests
running side by side on one machine never see each other's topics.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings
from ros_support import Probe, RosDomain, Spawner, next_domain

# No per-example deadline: the first example of a property test may include numba
# compiling the kernel under test (an empty cache after any edit of a compiled module),
# and wall time on a shared 2-core machine says nothing about correctness.
settings.register_profile("sideslip", deadline=None)
settings.load_profile("sideslip")


@pytest.fixture(scope="session", autouse=True)
def _observer_cache(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The UKF observer's disk cache in this session's temporary folder, not ~/.cache,
    from before the first fixture (module- and session-scoped ones too) to the end: a
    cache kept between runs would let a test read columns that an older filter wrote,
    and hide what a fresh machine computes."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SIDESLIP_CACHE", str(tmp_path_factory.getbasetemp() / "cache"))
        yield


@pytest.fixture
def ros_domain() -> RosDomain:
    domain_id = next_domain()
    # Also for rclpy in this process (a test's own context, the probe): loopback only.
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env = dict(os.environ)
    env.update(
        ROS_DOMAIN_ID=str(domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        PYTHONUNBUFFERED="1",
    )
    return RosDomain(domain_id, env)


@pytest.fixture(scope="session")
def compiled_kernels() -> None:
    """The simulator's and the LSTM engine's numba kernels, compiled (or loaded from the
    cache) once in this process before any node is spawned.

    numba checks its disk cache against each source file's modification time, so a fresh
    clone compiles again. Without this the first sim or estimator child would compile
    (about 15 s on an idle 2-core machine, more on a loaded one) inside a test's wait
    for its messages; the children load what this wrote.
    """
    from sideslip_estimator.lstm_kernel import compile_kernels
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.simulate import simulate
    from sideslip_sim.vehicle import load_vehicle

    simulate(load_vehicle("paper_sedan"), Maneuver("warm_up", "straight", 0.01, 10.0, 0.0))
    compile_kernels()


@pytest.fixture
def spawn(ros_domain: RosDomain, tmp_path: Path, compiled_kernels: None) -> Iterator[Spawner]:
    """Start child processes in the test's domain; all are stopped at teardown."""
    spawner = Spawner(ros_domain.env, tmp_path)
    yield spawner
    spawner.close()


@pytest.fixture
def probe(ros_domain: RosDomain) -> Iterator[Probe]:
    """A test-side rclpy node in the test's domain."""
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    p = Probe(ros_domain.domain_id)
    yield p
    p.close()


@pytest.fixture
def scratch_dir() -> Iterator[Path]:
    """A temporary directory outside pytest's tmp_path (for bags that tools create)."""
    with tempfile.TemporaryDirectory(prefix="sideslip-test-") as d:
        yield Path(d)
