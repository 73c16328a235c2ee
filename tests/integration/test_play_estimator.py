"""play_estimator.launch.xml without ``ros2 launch``: its two processes started with the
command lines the launch file gives them, player first (the order that lost the first
seconds of the bag), over real DDS."""

from __future__ import annotations

import re
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from ros_support import wait_for

from sideslip_msgs_py import topics
from sideslip_msgs_py.bag import write_bag
from sideslip_msgs_py.nodes.qos import profile_for
from sideslip_msgs_py.sample import SampleArrays, SensorNoiseSigma

ROOT = Path(__file__).resolve().parents[2]
LAUNCH = ROOT / "sideslip_estimator/launch/play_estimator.launch.xml"
ESTIMATOR_YAML = ROOT / "sideslip_estimator/config/estimator.yaml"
T0_NS = 1_700_000_000 * 10**9
STEP_NS = 2_500_000  # 400 Hz
WINDOW_STEPS = 100  # estimator.yaml: the first estimate is for the 100th sample


def bag_of(path: Path, n: int) -> Path:
    """``n`` samples of a car at 20 m/s sliding gently left and right (not physics)."""
    rng = np.random.default_rng(0)
    t = np.arange(n) * (STEP_NS * 1e-9)
    v_y = 0.8 * np.sin(np.pi * t)
    arrays = SampleArrays(
        stamp_ns=T0_NS + np.arange(n, dtype=np.int64) * STEP_NS,
        x_v_mps=20.0 + rng.normal(0, 0.1, n),
        y_v_mps=v_y + rng.normal(0, 0.1, n),
        x_a_mps2=rng.normal(0, 0.1, n),
        y_a_mps2=rng.normal(0, 0.1, n),
        yaw_rate_radps=0.3 * np.sin(np.pi * t),
        stl_m=0.02 * np.sin(np.pi * t),
        stl_rate_mps=0.02 * np.pi * np.cos(np.pi * t),
        truth_v_x_mps=np.full(n, 20.0),
        truth_v_y_mps=v_y,
        truth_yaw_rate_radps=0.3 * np.sin(np.pi * t),
    )
    return write_bag(path, arrays, sigma=SensorNoiseSigma.paper(), run_metadata={"seed": 0})


def player_args(bag: Path) -> list[str]:
    """The player's command line in the launch file with its defaults (clock:=true)."""
    root = ET.parse(LAUNCH).getroot()
    values = {a.get("name"): a.get("default") for a in root.iter("arg")} | {"bag": str(bag)}
    (player,) = [n for n in root.iter("node") if n.get("exec") == "sideslip-play" and n.get("if")]
    return re.sub(r"\$\(var (\w+)\)", lambda m: values[m.group(1)], player.get("args")).split()


def test_the_estimator_takes_the_bag_from_its_first_samples(spawn, probe, tmp_path):
    n = 800  # 2 s
    bag = bag_of(tmp_path / "drive", n)
    status = probe.subscribe(
        topics.SIDESLIP_STATUS, DiagnosticArray, profile_for(topics.SIDESLIP_STATUS)
    )
    player = spawn("sideslip-play", *player_args(bag))
    # The estimator starts once the player's publishers exist: a player that did not wait
    # would be playing by now (or be done).
    wait_for(
        lambda: probe.node.count_publishers(topics.IMU) or player.proc.poll() is not None,
        20,
        "the player's publishers",
    )
    estimator = spawn(
        "estimator_node",
        "--ros-args",
        "--params-file", str(ESTIMATOR_YAML),
        "-p", "backend:=kinematic",
        "-p", "use_sim_time:=true",
    )  # fmt: skip
    assert player.proc.wait(60) == 0, player.output()
    ended_ns = time.time_ns()
    # The estimator's own counters, from a status sent well after the last sample.
    wait_for(lambda: status and status[-1].recv_ns > ended_ns + 10**9, 10, "a final status")
    counts = {v.key: v.value for v in status[-1].msg.status[0].values}
    accepted, dropped = int(counts["accepted_samples"]), int(counts["dropped_samples"])
    # Gaps between accepted samples count as dropped; what is left is lost at the start.
    lost_at_start = n - accepted - dropped
    # 40 samples = 0.1 s of slack for a loaded machine; a player that does not wait
    # loses hundreds (185 here with the old launch file, 2-3 s in the issue).
    assert lost_at_start <= 40, (lost_at_start, counts, player.output())
    assert int(counts["estimates"]) >= n - lost_at_start - 3 * WINDOW_STEPS
    out = player.output()
    assert out.index("all 3 publisher(s) matched 1 subscriber(s) each; playing") < out.index(
        "played 4000 messages"
    )
    assert estimator.proc.poll() is None
