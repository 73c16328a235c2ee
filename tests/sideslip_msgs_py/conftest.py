"""Fixtures for sideslip_msgs_py tests: small real sample arrays and bags, no mocks."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py.bag import write_bag
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

STEP_NS = 2_500_000  # 400 Hz


def _make_arrays(n: int, *, truth: bool = True, seed: int = 0, t0_ns: int = 0) -> SampleArrays:
    """A smooth, plausible manoeuvre (sine steer at 20 m/s) plus noise; not physics."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * (STEP_NS * 1e-9)
    v_x = 20.0 + 0.5 * np.sin(0.3 * t)
    v_y = 0.8 * np.sin(2.0 * math.pi * 0.5 * t)
    r = 0.3 * np.sin(2.0 * math.pi * 0.5 * t + 0.2)
    cols = {
        "x_v_mps": v_x + rng.normal(0, 0.28, n),
        "y_v_mps": v_y + rng.normal(0, 0.28, n),
        "x_a_mps2": rng.normal(0, 0.1, n),
        "y_a_mps2": v_x * r + rng.normal(0, 0.1, n),
        "yaw_rate_radps": r + rng.normal(0, 0.0035, n),
        "stl_m": 0.02 * np.sin(2.0 * math.pi * 0.5 * t),
        "stl_rate_mps": 0.02 * math.pi * np.cos(2.0 * math.pi * 0.5 * t),
    }
    if truth:
        cols |= {"truth_v_x_mps": v_x, "truth_v_y_mps": v_y, "truth_yaw_rate_radps": r}
    return SampleArrays(stamp_ns=t0_ns + np.arange(n, dtype=np.int64) * STEP_NS, **cols)


@pytest.fixture
def make_arrays() -> Callable[..., SampleArrays]:
    """Factory: ``make_arrays(n, truth=True, seed=0, t0_ns=0)``."""
    return _make_arrays


@pytest.fixture
def run_metadata() -> dict[str, object]:
    return {"maneuver": "sine_steer", "seed": 7, "speed_kmh": 72.0, "tags": ["test"]}


@pytest.fixture
def small_bag(tmp_path: Path, run_metadata: dict[str, object]) -> tuple[Path, SampleArrays]:
    """A 2-s bag (800 steps at 400 Hz) with ground truth."""
    arrays = _make_arrays(800, t0_ns=1_700_000_000 * 10**9)
    path = write_bag(
        tmp_path / "run", arrays, sigma=SensorNoiseSigma.paper(), run_metadata=run_metadata
    )
    return path, arrays
