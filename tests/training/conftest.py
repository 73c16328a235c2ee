"""Fixtures for the training tests: small real bags (simulated, or written from arrays)."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from sideslip_msgs_py.bag import write_bag
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

STEP_NS = 2_500_000  # 400 Hz


@pytest.fixture(scope="module", autouse=True)
def _torch_threads(request: pytest.FixtureRequest):
    """Torch on every core through the modules that say ``TORCH_ON_EVERY_CORE = True``
    (they fine-tune and score shipped models: :func:`torch_support.every_core`)."""
    if not getattr(request.module, "TORCH_ON_EVERY_CORE", False):
        yield
        return
    from torch_support import every_core

    with every_core():
        yield


def _make_arrays(
    n: int,
    *,
    truth: bool = True,
    seed: int = 0,
    t0_ns: int = 0,
    v_x_mps: float = 20.0,
    stamps_ns: np.ndarray | None = None,
) -> SampleArrays:
    """A smooth sine-steer-like signal (not physics) plus noise, at 400 Hz by default."""
    rng = np.random.default_rng(seed)
    stamp = (
        t0_ns + np.arange(n, dtype=np.int64) * STEP_NS
        if stamps_ns is None
        else np.asarray(stamps_ns, np.int64)
    )
    t = (stamp - stamp[0]) * 1e-9
    v_x = v_x_mps + 0.5 * np.sin(0.3 * t)
    v_y = 0.8 * np.sin(2.0 * math.pi * 0.5 * t + seed)
    r = 0.3 * np.sin(2.0 * math.pi * 0.5 * t + 0.2 + seed)
    cols = {
        "x_v_mps": v_x + rng.normal(0, 0.28, n),
        "y_v_mps": v_y + rng.normal(0, 0.28, n),
        "x_a_mps2": rng.normal(0, 0.1, n),
        "y_a_mps2": v_x * r + rng.normal(0, 0.1, n),
        "yaw_rate_radps": r + rng.normal(0, 0.0035, n),
        "stl_m": 0.02 * np.sin(2.0 * math.pi * 0.5 * t + seed),
        "stl_rate_mps": 0.02 * math.pi * np.cos(2.0 * math.pi * 0.5 * t + seed),
    }
    if truth:
        cols |= {"truth_v_x_mps": v_x, "truth_v_y_mps": v_y, "truth_yaw_rate_radps": r}
    return SampleArrays(stamp_ns=stamp, **cols)


@pytest.fixture
def make_arrays() -> Callable[..., SampleArrays]:
    """Factory: ``make_arrays(n, truth=True, seed=0, t0_ns=0, v_x_mps=20.0, stamps_ns=None)``."""
    return _make_arrays


@pytest.fixture
def write_arrays(tmp_path: Path) -> Callable[..., Path]:
    """Factory: ``write_arrays(name, arrays, folder=tmp_path)`` → a rosbag2 directory."""

    def write(name: str, arrays: SampleArrays, folder: Path | None = None) -> Path:
        out = (folder or tmp_path) / name
        out.parent.mkdir(parents=True, exist_ok=True)
        return write_bag(
            out, arrays, sigma=SensorNoiseSigma.paper(), run_metadata={"name": name}, compress=False
        )

    return write


@pytest.fixture(scope="session")
def sim_bag_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A ``sideslip-generate``-style folder (index.json + 4 bags of 1 s, 400 samples each)."""
    from sideslip_sim.generate import generate, single_vehicle
    from sideslip_sim.maneuvers import Maneuver
    from sideslip_sim.vehicle import load_vehicle

    out = tmp_path_factory.mktemp("sim_bags")
    maneuvers = [
        Maneuver("dlc_70", "double_lane_change", 1.0, 70.0, 0.0),
        Maneuver("sine_60", "sine_steer", 1.0, 60.0, 0.0, seed=1),
        Maneuver("sine_80", "sine_steer", 1.0, 80.0, 0.0, seed=2),
        Maneuver("straight_50", "straight", 1.0, 50.0, 0.0),
    ]
    runs = single_vehicle(load_vehicle("paper_sedan"), maneuvers)
    generate(runs, out, preset_name="test", progress=False)
    return out


def _record_foreign(folder: Path, count: int, seed: int, rng_seed: int) -> None:
    """``count`` fleet-style runs of ``compact_rwd`` (fleet seed ``seed``) written into
    ``folder`` as another stack records them (see :func:`foreign_bags`)."""
    from foreign_bag import Truth, write_foreign_bag

    from sideslip_sim.presets import fleet_runs
    from sideslip_sim.simulate import simulate
    from sideslip_sim.vehicle import load_vehicle

    rng = np.random.default_rng(rng_seed)
    car = load_vehicle("compact_rwd")
    for i, vr in enumerate(fleet_runs([car] * math.ceil(count / 4), count, seed)):
        s = simulate(vr.vehicle, vr.maneuver)
        k = slice(None, None, 4)  # 400 Hz -> 100 Hz
        n = s.t_s[k].size
        truth = Truth(
            stamp_ns=10**15 + np.round(s.t_s[k] * 1e9).astype(np.int64),
            x_v=s.u_mps[k],
            y_v=s.v_mps[k],
            x_a=s.ax_mps2[k] + rng.normal(0, 0.1, n),
            y_a=s.ay_mps2[k] + rng.normal(0, 0.1, n),
            r=s.yaw_rate_radps[k] + rng.normal(0, math.radians(0.2), n),
            stl=s.stl_m[k] + rng.normal(0, 1e-3, n),
            yaw=s.psi_rad[k] + 0.7,
        )
        write_foreign_bag(folder / f"drive{i:02d}", truth)


@pytest.fixture(scope="session")
def foreign_bags(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Two minutes of ``compact_rwd`` driving (12 runs) recorded as another stack would:
    other topics and types, 100 Hz, a steering-wheel angle, the reference velocity from a
    GNSS/INS in the east/north frame; the paper's noise on the IMU and the steering.
    Returns the folder of bags and the topic map that reads them."""
    import yaml
    from foreign_bag import TOPIC_MAP

    folder = tmp_path_factory.mktemp("foreign")
    _record_foreign(folder, 12, seed=5, rng_seed=3)
    topic_map = folder / "map.yaml"
    topic_map.write_text(yaml.safe_dump(TOPIC_MAP))
    return folder, topic_map


@pytest.fixture(scope="session")
def foreign_new_drives(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Three other drives of the same car, recorded the same way (other fleet seed and
    noise): read with :func:`foreign_bags`' topic map."""
    folder = tmp_path_factory.mktemp("foreign_new")
    _record_foreign(folder, 3, seed=11, rng_seed=4)
    return folder


@pytest.fixture
def compact_rwd_description(tmp_path: Path) -> Path:
    """``compact_rwd``'s description in a temporary file."""
    from described_cars import describe_compact_rwd

    return describe_compact_rwd(tmp_path / "my_car.yaml")


@pytest.fixture(scope="module")
def paper_windows(sim_bag_dir: Path):
    """Training and validation windows (paper features, stride 5) of :func:`sim_bag_dir`
    split by bag, and their normalizer, for trainer-level tests (one torch thread)."""
    import torch

    from sideslip_msgs_py.features import feature_set
    from sideslip_training.config import WINDOW_STEPS
    from sideslip_training.dataset import load_runs
    from sideslip_training.normalize import Normalizer
    from sideslip_training.splits import split_runs
    from sideslip_training.windows import WindowIndex

    torch.set_num_threads(1)
    features = feature_set("paper")
    runs, _ = load_runs([sim_bag_dir])
    train_runs, val_runs = split_runs(runs, 0.25, 0)
    norm = Normalizer.fit(train_runs, features)
    train = WindowIndex.build(train_runs, features, norm, WINDOW_STEPS, 5)
    val = WindowIndex.build(val_runs, features, norm, WINDOW_STEPS, 5)
    return train, val, norm
