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


@pytest.fixture
def ros_domain() -> RosDomain:
    domain_id = next_domain()
    env = dict(os.environ)
    env.update(
        ROS_DOMAIN_ID=str(domain_id),
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        PYTHONUNBUFFERED="1",
    )
    return RosDomain(domain_id, env)


@pytest.fixture
def spawn(ros_domain: RosDomain, tmp_path: Path) -> Iterator[Spawner]:
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
