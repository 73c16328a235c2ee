"""Sensor model: exact signals of a run → what cheap sensors report, with Gaussian noise.

Noise is zero-mean, independent per channel and per sample, with σ from a
`SensorNoiseSigma` (the paper's profile by default: 1 km/h, 0.1 m/s², 0.2 deg/s, 1 mm).
Which σ a channel gets is the contract registry's (``sideslip_msgs_py.channels``):
channels are drawn in registry order, so a channel appended there leaves the noise of
the others as it was. It is drawn from a numpy PCG64 generator seeded per run, so a bag
is reproducible whatever order or process generated it. Ground truth is never noisy.
The STL rate (JointState velocity) carries no noise: the paper gives no σ for it, and
differencing the noisy STL would make a useless channel.

:func:`exact_samples` is the one place that says which simulator output feeds which
contract channel.
"""

from __future__ import annotations

import zlib

import numpy as np

from sideslip_msgs_py import channels as registry
from sideslip_msgs_py.sample import TRUTH_CHANNELS, SampleArrays, SensorNoiseSigma
from sideslip_msgs_py.timing import STEP_NS
from sideslip_sim.imu_mounting import ImuMounting, mounted_accelerations
from sideslip_sim.simulate import SimResult

NOISE_PROFILES = ("paper", "none")


def noise_profile(name: str) -> SensorNoiseSigma:
    """The named noise profile; unknown names are an error naming the known ones."""
    if name == "paper":
        return SensorNoiseSigma.paper()
    if name == "none":
        return SensorNoiseSigma.none()
    raise ValueError(f"unknown noise profile {name!r}; known: {', '.join(NOISE_PROFILES)}")


def run_seed(base_seed: int, run_name: str) -> np.random.SeedSequence:
    """Per-run seed: independent of run order and of which worker runs it."""
    return np.random.SeedSequence([int(base_seed) & 0xFFFFFFFF, zlib.crc32(run_name.encode())])


def exact_samples(
    result: SimResult, start_stamp_ns: int = 0, imu: ImuMounting | None = None
) -> SampleArrays:
    """The run's exact signals as contract samples, with ground truth attached.

    Stamps are start + k·dt in integer nanoseconds (2.5 ms = 2 500 000 ns, exact).
    ``imu``: where the IMU sits and its frame (:mod:`sideslip_sim.imu_mounting`); by
    default the contract's ideal IMU (CG acceleration, horizontal frame).
    """
    dt_ns = round((result.t_s[1] - result.t_s[0]) * 1e9) if len(result) > 1 else STEP_NS
    stamps = start_stamp_ns + np.arange(len(result), dtype=np.int64) * dt_ns
    ax, ay = result.ax_mps2, result.ay_mps2
    if imu is not None and not imu.ideal:
        ax, ay = mounted_accelerations(
            imu,
            result.t_s,
            ax,
            ay,
            result.yaw_rate_radps,
            result.roll_rad,
            result.pitch_rad,
            result.gravity_x_mps2,
            result.gravity_y_mps2,
        )
    return SampleArrays(
        stamp_ns=stamps,
        x_v_mps=result.u_mps,
        y_v_mps=result.v_mps,
        x_a_mps2=ax,
        y_a_mps2=ay,
        yaw_rate_radps=result.yaw_rate_radps,
        stl_m=result.stl_m,
        stl_rate_mps=result.stl_rate_mps,
        truth_v_x_mps=result.u_mps,
        truth_v_y_mps=result.v_mps,
        truth_yaw_rate_radps=result.yaw_rate_radps,
    )


def add_noise(
    samples: SampleArrays, sigma: SensorNoiseSigma, seed: np.random.SeedSequence | int
) -> SampleArrays:
    """Sensor channels plus Gaussian noise; stamps and ground truth unchanged."""
    rng = np.random.Generator(np.random.PCG64(seed))
    n = len(samples)

    def noisy(values: np.ndarray, std: float) -> np.ndarray:
        # Draw even when std == 0 so that changing one σ leaves the others' noise intact.
        return values + std * rng.standard_normal(n)

    columns = {name: getattr(samples, name) for name in TRUTH_CHANNELS}
    for ch in registry.SENSOR:  # registry order: the draw order
        values = getattr(samples, ch.name)
        columns[ch.name] = values if ch.sigma is None else noisy(values, getattr(sigma, ch.sigma))
    return SampleArrays(stamp_ns=samples.stamp_ns, **columns)
