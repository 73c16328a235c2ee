"""Run an rclpy node until SIGINT or SIGTERM, then shut down cleanly with exit code 0.

rclpy's own signal handlers shut the context down from inside the handler, which
races with threads that are still publishing (the sim node publishes from its own
thread) and turns SIGTERM into an exception in ``spin``. We install plain handlers
that only set a flag; the spin loop notices it within one wait period and the node's
``close()`` runs while the context is still valid.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from collections.abc import Callable, Sequence
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

SPIN_PERIOD_S = 0.05
"""Longest time between a signal and the spin loop noticing it."""


def make_executor(context: Any = None) -> Any:
    """The executor nodes spin on: rclpy's C++ EventsExecutor unless
    ``SIDESLIP_EXECUTOR=single_threaded`` asks for the pure-Python one.

    Why the experimental one: over DDS at 400 Hz it cuts the estimator's end-to-end
    latency p99 from about 2.7 to 1.9 ms on the 2-core reference machine (`make bench`,
    section ros_runtime). Known limit: subscription callbacks that take
    ``(msg, message_info)`` crash it, so ours take the message only.
    """
    if os.environ.get("SIDESLIP_EXECUTOR", "events") == "single_threaded":
        return SingleThreadedExecutor(context=context)
    try:
        from rclpy.experimental import EventsExecutor
    except ImportError:  # an rclpy older than the PyPI 7.1.6 wheels (a stock install)
        return SingleThreadedExecutor(context=context)
    return EventsExecutor(context=context)


class SpinThread:
    """Spins ``executor`` on a daemon thread until :meth:`stop`.

    Why not a bare ``while context.ok(): spin_once()`` thread: rclpy does not allow a
    node to be destroyed while another thread is inside ``spin_once`` (ros2/rclpy#255,
    #260); with messages still arriving it can crash the whole process with a
    segmentation fault. :meth:`stop` returns only once the thread has left the
    executor, so destroying the node afterwards is safe.
    """

    def __init__(self, executor: Any, context: Any, name: str = "spin") -> None:
        self._executor = executor
        self._context = context
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name=name, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        try:
            while not self._stop.is_set() and self._context.ok():
                self._executor.spin_once(timeout_sec=SPIN_PERIOD_S)
        except (ExternalShutdownException, RuntimeError):
            pass  # the context was shut down under the spin: nothing left to serve

    def stop(self, timeout_s: float = 5.0) -> bool:
        """Stop spinning; True once the thread has left ``spin_once`` (within
        ``timeout_s``), False if it is still inside (then the node must not be destroyed)."""
        self._stop.set()
        self._thread.join(timeout_s)
        return not self._thread.is_alive()

    def close(self, node: Any) -> None:
        """Stop spinning, then shut down the executor, destroy ``node`` and shut down the
        context, in that order. Raises RuntimeError (destroying nothing) if the thread
        does not leave the executor."""
        if not self.stop():
            raise RuntimeError(f"{node.get_name()}: spin thread still inside the executor")
        self._executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        if self._context.ok():
            rclpy.shutdown(context=self._context)


class StopFlag:
    """Set by SIGINT/SIGTERM (or by a node that has finished its work)."""

    def __init__(self) -> None:
        self._event = threading.Event()
        self.signal_name: str | None = None
        """Why it was set: SIGINT, SIGTERM, finished, error, ..."""

    def set(self, reason: str | None = None) -> None:
        if reason is not None and self.signal_name is None:
            self.signal_name = reason
        self._event.set()

    def is_set(self) -> bool:
        return self._event.is_set()

    def wait(self, timeout_s: float) -> bool:
        return self._event.wait(timeout_s)


def install_signal_handlers(flag: StopFlag) -> None:
    """SIGINT and SIGTERM set ``flag``."""

    def handler(signum: int, _frame: Any) -> None:
        # Repeated signals are ignored: a second Ctrl-C while a recorder writes its
        # bag's summary must not leave the bag without one. SIGKILL still ends anything.
        flag.set(signal.Signals(signum).name)

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


def run(
    make_node: Callable[[StopFlag], Any],
    argv: Sequence[str] | None = None,
) -> int:
    """Create the node with ``make_node(flag)``, spin until the flag is set, clean up.

    ``make_node`` may raise ``SystemExit`` (bad parameters): the exit code is passed on
    after rclpy is shut down. The node may also set the flag itself when its work is
    done (a player at the end of a bag). Returns the process exit code.

    A node's ``close()`` that returns ``False`` says one of its threads still uses it
    (a publisher that did not stop in time): the node is then neither destroyed nor is
    rclpy shut down, since either under a running thread can crash the process or raise
    in that thread; the thread ends on the flag and the process exits after it.
    """
    flag = StopFlag()
    install_signal_handlers(flag)
    args = list(sys.argv if argv is None else argv)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    node = None
    code = 0
    executor = make_executor()
    try:
        node = make_node(flag)
        executor.add_node(node)
        while not flag.is_set() and rclpy.ok():
            executor.spin_once(timeout_sec=SPIN_PERIOD_S)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 2
        if not isinstance(exc.code, int) and exc.code:
            print(exc.code, file=sys.stderr)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        released = True
        if node is not None:
            close = getattr(node, "close", None)
            if close is not None:
                released = close() is not False
            if released:
                executor.remove_node(node)
                node.destroy_node()
            else:
                print(
                    "a worker thread is still running: leaving the node to it until it ends",
                    file=sys.stderr,
                )
        if released:
            executor.shutdown(timeout_sec=1.0)
            if rclpy.ok():
                rclpy.shutdown()
    if flag.signal_name == "error":  # the node failed after start-up (it logged why)
        code = code or 1
    return code


def user_args(argv: Sequence[str]) -> list[str]:
    """The arguments before ``--ros-args`` (argv[0] excluded): a node's own options."""
    args = list(argv[1:])
    return args[: args.index("--ros-args")] if "--ros-args" in args else args


def wants_help(argv: Sequence[str]) -> bool:
    return any(a in ("-h", "--help") for a in user_args(argv))
