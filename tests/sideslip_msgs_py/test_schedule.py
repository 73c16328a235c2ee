"""The absolute publishing schedule shared by the bag player and the sim node, and the
one wait-until-deadline helper both pace through (``sideslip_msgs_py.schedule``)."""

from __future__ import annotations

import threading
import time

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sideslip_msgs_py.nodes.runtime import StopFlag
from sideslip_msgs_py.schedule import SPIN_S, WATCH_S, Schedule, wait_until

T0_NS = 1_700_000_000 * 10**9
STEP_NS = 2_500_000  # 400 Hz
STOPS = [threading.Event, StopFlag]


# --- Schedule ---------------------------------------------------------------------------------


def test_schedule_is_absolute_so_late_messages_do_not_shift_later_deadlines() -> None:
    schedule = Schedule(start_ns=5_000, t_first_ns=T0_NS, rate=2.0)
    assert schedule.deadline_ns(T0_NS) == 5_000
    assert schedule.deadline_ns(T0_NS + 1_000_000_000) == 5_000 + 500_000_000
    # Deadlines depend only on the log time, never on when the previous one was met.
    many = [schedule.deadline_ns(T0_NS + i * STEP_NS) for i in range(10_000)]
    assert many[-1] == 5_000 + round(9_999 * STEP_NS / 2.0)
    assert schedule.bag_time_ns(5_000 + 250_000_000) == T0_NS + 500_000_000
    assert schedule.bag_time_ns(0) == T0_NS  # before the start: the first message's time
    with pytest.raises(ValueError, match="rate"):
        Schedule(0, 0, rate=0.0)


@pytest.mark.parametrize("rate", [0.0, -1.0, float("inf"), float("nan")])
def test_a_rate_that_is_not_finite_and_positive_is_refused_naming_it(rate: float) -> None:
    with pytest.raises(ValueError, match=f"rate must be a finite number > 0, got {rate}"):
        Schedule(0, T0_NS, rate)


@given(
    rate=st.floats(min_value=0.01, max_value=100.0),
    offsets=st.lists(st.integers(min_value=0, max_value=10**12), min_size=2, max_size=50),
)
def test_deadlines_never_run_backwards_as_log_time_advances(
    rate: float, offsets: list[int]
) -> None:
    schedule = Schedule(123, T0_NS, rate)
    deadlines = [schedule.deadline_ns(T0_NS + t) for t in sorted(offsets)]
    assert deadlines == sorted(deadlines)
    assert deadlines[0] >= schedule.start_ns


def test_a_wall_clock_schedule_keeps_the_first_stamp_and_the_rate() -> None:
    schedule = Schedule.at_wall_clock(T0_NS, rate=2.0)
    assert schedule.t_first_ns == T0_NS and schedule.rate == 2.0
    assert schedule.deadline_ns(T0_NS) == schedule.start_ns
    assert schedule.deadline_ns(T0_NS + 2_000_000_000) == schedule.start_ns + 1_000_000_000


# --- wait_until -------------------------------------------------------------------------------


@pytest.mark.parametrize("make_stop", STOPS)
@pytest.mark.parametrize(
    "ahead_s",
    [-0.001, 0.0, SPIN_S / 2, 2 * SPIN_S, 0.002, 2 * WATCH_S, 0.03],
    ids=["past", "now", "spin-only", "sleep", "sleep-long", "watched", "watched-long"],
)
def test_waiting_never_returns_before_the_deadline(make_stop, ahead_s: float) -> None:
    stop = make_stop()
    deadline_ns = time.monotonic_ns() + round(ahead_s * 1e9)
    assert wait_until(deadline_ns, stop) is True
    assert time.monotonic_ns() >= deadline_ns


@pytest.mark.parametrize("make_stop", STOPS)
@pytest.mark.parametrize("ahead_s", [-0.001, 0.001, 600.0])
def test_a_stop_requested_before_the_wait_returns_false(make_stop, ahead_s: float) -> None:
    stop = make_stop()
    stop.set()
    assert wait_until(time.monotonic_ns() + round(ahead_s * 1e9), stop) is False


@pytest.mark.parametrize("make_stop", STOPS)
def test_a_stop_requested_during_a_long_wait_ends_it_with_false(make_stop) -> None:
    stop = make_stop()
    timer = threading.Timer(0.05, stop.set)
    timer.start()
    try:
        assert wait_until(time.monotonic_ns() + 600 * 10**9, stop) is False
    finally:
        timer.cancel()
