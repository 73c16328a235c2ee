"""Adding a sensor channel on an existing topic is one registry entry.

A copy of ``sideslip_msgs_py`` gets one more :class:`~sideslip_msgs_py.channels.Channel`
(a roll rate on ``/vehicle/imu`` ``angular_velocity.x``) appended to its registry and
nothing else; a fresh interpreter that imports that copy (and the real simulator and
estimator) then carries the channel through the sample records, the rclpy and rosbags
messages, the IMU covariance, the byte codec, a bag, the simulator's noise and the
estimator's checks, window and replay. The consumer-side tables a channel needs (its
bound, its σ parameter) are checked against the registry here too.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from sideslip_estimator.inputs import InputLimits
from sideslip_msgs_py import channels
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma
from sideslip_sim.sensors import add_noise

ROOT = Path(__file__).resolve().parents[1]

ENTRY = """
SENSOR = (
    *SENSOR,
    Channel(
        "roll_rate_radps", "φ̇", "rad/s", "roll rate, positive right side down",
        topics.IMU, "angular_velocity.x", "yaw_rate_radps", "yaw_rate_radps", lateral=True,
    ),
)
"""

SCRIPT = r"""
import sys
from pathlib import Path

import numpy as np
from rclpy.serialization import deserialize_message, serialize_message

from sideslip_estimator.backends import create_backend
from sideslip_estimator.estimator import Estimator, EstimatorParams
from sideslip_estimator.inputs import InputRejected, check_imu, InputLimits
from sideslip_estimator.replay import replay, replay_columns
from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import read_bag, write_bag
from sideslip_msgs_py.features import CHANNELS
from sideslip_msgs_py.messages import (
    RclpyMessages, imu_fields, messages_to_sample, sample_to_messages,
)
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma
from sideslip_sim.sensors import add_noise

out = Path(sys.argv[1])
assert CHANNELS[-1] == "roll_rate_radps"
n = 400
t = np.arange(n) * 0.0025
cols = dict(
    x_v_mps=20.0 + t, y_v_mps=0.3 * np.sin(t), x_a_mps2=0.1 + 0 * t, y_a_mps2=2.0 * np.cos(t),
    yaw_rate_radps=0.1 * np.sin(t), stl_m=0.01 * np.sin(t), stl_rate_mps=0.01 * np.cos(t),
    roll_rate_radps=0.05 * np.cos(3 * t),
    truth_v_x_mps=20.0 + t, truth_v_y_mps=0.3 * np.sin(t), truth_yaw_rate_radps=0.1 * np.sin(t),
)
exact = SampleArrays(stamp_ns=10**9 + np.arange(n, dtype=np.int64) * 2_500_000, **cols)
sigma = SensorNoiseSigma.paper()

# producer: the simulator's noise covers the new channel (σ of the yaw rate)
noisy = add_noise(exact, sigma, 7)
assert not np.array_equal(noisy.roll_rate_radps, exact.roll_rate_radps)

# contract: rclpy messages, the IMU covariance, a bag
rclpy_msgs = RclpyMessages()
msgs = sample_to_messages(noisy.row(3), rclpy_msgs, sigma)
imu = msgs[topics.IMU]
assert imu.angular_velocity.x == noisy.roll_rate_radps[3]
assert imu.angular_velocity_covariance[0] == sigma.yaw_rate_radps**2
back = {k: deserialize_message(serialize_message(m), type(m)) for k, m in msgs.items()}
assert messages_to_sample(back) == noisy.row(3)
assert imu_fields(imu).roll_rate_radps == noisy.roll_rate_radps[3]
bag = write_bag(out / "bag", noisy, sigma=sigma, run_metadata={})
assert read_bag(bag).samples == noisy

# consumer: the estimator checks it, windows it and replays it
bad = imu_fields(imu)._replace(roll_rate_radps=float("nan"))
try:
    check_imu("/imu", bad, InputLimits())
    raise AssertionError("a NaN roll rate passed the checks")
except InputRejected as err:
    assert "angular_velocity.x" in str(err)
est = Estimator(create_backend("kinematic", {}, 100), EstimatorParams(window_steps=100))
result = replay(est, replay_columns(noisy))
assert result.rejected == 0 and np.isfinite(result.beta_rad[-1])
np.testing.assert_array_equal(est.window.rows()[:, -1], noisy.roll_rate_radps[-100:])
from sideslip_msgs_py.mirror import mirrored
np.testing.assert_array_equal(mirrored(noisy).roll_rate_radps, -noisy.roll_rate_radps)
np.savez(
    out / "channels.npz",
    stamp_ns=exact.stamp_ns,
    **{c: getattr(noisy, c) for c in cols},
    **{f"exact_{c}": getattr(exact, c) for c in cols},
)
"""


def _copy_with_entry(tmp_path: Path) -> Path:
    package = tmp_path / "sideslip_msgs_py"
    shutil.copytree(
        ROOT / "sideslip_msgs_py" / "sideslip_msgs_py",
        package / "sideslip_msgs_py",
        ignore=shutil.ignore_patterns("__pycache__"),
    )
    registry = package / "sideslip_msgs_py" / "channels.py"
    registry.write_text(registry.read_text(encoding="utf-8") + ENTRY, encoding="utf-8")
    return package


def test_a_channel_added_to_the_registry_alone_reaches_bag_sim_noise_and_estimator(
    tmp_path: Path,
) -> None:
    package = _copy_with_entry(tmp_path)
    env = dict(os.environ)
    paths = [package] + [ROOT / p for p in ("sideslip_sim", "sideslip_estimator")]
    env["PYTHONPATH"] = os.pathsep.join([*map(str, paths), env.get("PYTHONPATH", "")])
    run = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(tmp_path)],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-3000:]

    # Appending a channel leaves the noise of every other channel as it was.
    got = np.load(tmp_path / "channels.npz")
    names = [f.name for f in dataclasses.fields(SampleArrays) if f.name != "stamp_ns"]
    exact = SampleArrays(stamp_ns=got["stamp_ns"], **{n: got[f"exact_{n}"] for n in names})
    noisy = add_noise(exact, SensorNoiseSigma.paper(), 7)
    for name in names:
        np.testing.assert_array_equal(getattr(noisy, name), got[name], err_msg=name)


def test_every_model_input_has_a_bound_and_every_sigma_a_sim_parameter() -> None:
    limits = {f.name for f in dataclasses.fields(InputLimits)}
    for ch in channels.SENSOR:
        if ch.limit is not None:
            assert ch.limit in limits, ch.name
    from sideslip_sim.node_parameters import PARAMETERS, SigmaOverride

    names = {p.name for p in PARAMETERS}
    assert {f"sigma.{n.name}" for n in channels.NOISE} <= names
    assert [f.name for f in dataclasses.fields(SigmaOverride)] == [n.name for n in channels.NOISE]
