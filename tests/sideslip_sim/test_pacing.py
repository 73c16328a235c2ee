"""Pacing the sim node's steps: never before a step is due, not at all when unpaced, a
stop ends it, and the closing log line (no ROS)."""

from __future__ import annotations

import re
import threading
import time

import pytest

from sideslip_sim.pacing import Pacer

HOUR_NS = 3600 * 10**9


@pytest.mark.parametrize("real_time_factor", [1.0, 4.0])
def test_paced_steps_are_never_published_before_they_are_due(real_time_factor: float) -> None:
    pacer = Pacer(real_time_factor, threading.Event())
    first = time.time_ns()
    for k in range(5):
        assert pacer.wait_for(first + k * 2_000_000)
        pacer.count_published()
    assert len(pacer.lateness_ns) == 5 and min(pacer.lateness_ns) >= 0
    assert pacer.steps_published == 5


@pytest.mark.parametrize("real_time_factor", [0.0, float("inf")])
def test_unpaced_steps_never_wait(real_time_factor: float) -> None:
    pacer = Pacer(real_time_factor, threading.Event())
    assert pacer.wait_for(time.time_ns() + HOUR_NS)  # an hour ahead, and no wait
    assert not pacer.lateness_ns


@pytest.mark.parametrize("real_time_factor", [0.0, 1.0])
def test_a_stop_ends_the_pacing(real_time_factor: float) -> None:
    stop = threading.Event()
    pacer = Pacer(real_time_factor, stop)
    stop.set()
    assert not pacer.wait_for(time.time_ns() + HOUR_NS)


def test_the_summary_counts_steps_and_gives_lateness_percentiles_in_ms() -> None:
    pacer = Pacer(1.0, threading.Event())
    assert pacer.summary() == "0 steps published; lateness p50/p99/max 0.000/0.000/0.000 ms"
    pacer.lateness_ns.extend([0, 1_000_000, 2_000_000])
    for _ in range(3):
        pacer.count_published()
    assert re.fullmatch(
        r"3 steps published; lateness p50/p99/max 1\.000/1\.980/2\.000 ms", pacer.summary()
    )
