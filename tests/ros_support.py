"""Helpers for the multi-process ROS 2 tests (imported by conftest.py and by tests).

Nodes and tools run as real child processes (the installed console scripts); the test
talks to them through a :class:`Probe`, an rclpy node in its own context spun on a
thread. Matching on loopback can take seconds: every wait polls a condition with a
timeout (:func:`wait_for`), none sleeps a fixed time.
"""

from __future__ import annotations

import itertools
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

BIN = Path(sys.executable).parent
_domains = itertools.count()


def next_domain() -> int:
    """A DDS domain id for one test, spread over 1..100 by pid so that concurrent
    pytest processes on one machine rarely share one (above ~101 Fast DDS's ports
    reach Linux's ephemeral range)."""
    return 1 + (os.getpid() * 13 + next(_domains)) % 100


def wait_for(predicate: Callable[[], Any], timeout_s: float, what: str, poll_s: float = 0.02):
    """Poll ``predicate`` until it returns something truthy; fail the test on timeout."""
    deadline = time.monotonic() + timeout_s
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout_s:.1f} s waiting for {what}")
        time.sleep(poll_s)


@dataclass
class RosDomain:
    """A DDS domain id and the environment that confines child processes to it."""

    domain_id: int
    env: dict[str, str]


@dataclass
class Child:
    """A node or tool running as a child process, its output captured in a file."""

    name: str
    proc: subprocess.Popen[bytes]
    log_path: Path

    def output(self) -> str:
        return self.log_path.read_text(errors="replace")

    def stop(self, sig: int = signal.SIGINT, timeout_s: float = 10.0) -> tuple[int, float]:
        """Send ``sig``; return (exit code, seconds until exit). Kills it after the timeout."""
        if self.proc.poll() is not None:
            return self.proc.returncode, 0.0
        start = time.monotonic()
        self.proc.send_signal(sig)
        try:
            code = self.proc.wait(timeout_s)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            pytest.fail(f"{self.name} did not stop within {timeout_s} s of signal {sig}")
        return code, time.monotonic() - start


@dataclass
class Spawner:
    env: dict[str, str]
    tmp: Path
    children: list[Child] = field(default_factory=list)

    def __call__(self, executable: str, *args: str, name: str | None = None) -> Child:
        """Start an installed console script (from this venv) with ``args``."""
        name = name or executable
        log_path = self.tmp / f"{name}-{len(self.children)}.log"
        with log_path.open("wb") as log:
            proc = subprocess.Popen(
                [str(BIN / executable), *args],
                env=self.env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        child = Child(name, proc, log_path)
        self.children.append(child)
        return child

    def close(self) -> None:
        for child in self.children:
            if child.proc.poll() is None:
                child.proc.send_signal(signal.SIGINT)
        for child in self.children:
            try:
                child.proc.wait(5)
            except subprocess.TimeoutExpired:
                child.proc.kill()
                child.proc.wait()


@dataclass
class Received:
    """One message a probe subscription received, with its local receive time."""

    msg: Any
    recv_ns: int


class Probe:
    """An rclpy node in its own context, spinning on a background thread."""

    def __init__(self, domain_id: int, name: str = "probe") -> None:
        import rclpy
        from rclpy.context import Context

        from sideslip_msgs_py.nodes.runtime import SpinThread, make_executor

        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = rclpy.create_node(name, context=self.context)
        # The C++ events executor, as the nodes use: the Python one drops messages at
        # the few kHz a probe sees when it listens to several 400-Hz topics.
        self.executor = make_executor(self.context)
        self.executor.add_node(self.node)
        self._lock = threading.Lock()
        self._spinner = SpinThread(self.executor, self.context, name=f"{name}-spin")

    def subscribe(
        self, topic: str, msg_type: Any, qos: Any = 10, *, raw: bool = False
    ) -> list[Received]:
        """Collect every message on ``topic`` into the returned list."""
        inbox: list[Received] = []

        def on_message(msg: Any) -> None:
            now = time.time_ns()
            with self._lock:
                inbox.append(Received(msg, now))

        self.node.create_subscription(msg_type, topic, on_message, qos, raw=raw)
        return inbox

    def publisher(self, topic: str, msg_type: Any, qos: Any = 10) -> Any:
        return self.node.create_publisher(msg_type, topic, qos)

    def wait_for_publishers(self, topic: str, count: int = 1, timeout_s: float = 20.0) -> None:
        wait_for(
            lambda: self.node.count_publishers(topic) >= count,
            timeout_s,
            f"{count} publisher(s) on {topic}",
        )

    def wait_for_subscribers(self, publisher: Any, count: int = 1, timeout_s: float = 20.0):
        wait_for(
            lambda: publisher.get_subscription_count() >= count,
            timeout_s,
            f"{count} subscriber(s) on {publisher.topic_name}",
        )

    def close(self) -> None:
        # The spin thread leaves the executor before anything is destroyed: destroying
        # a node under a spinning thread once crashed the pytest process (SIGSEGV).
        try:
            self._spinner.close(self.node)
        except RuntimeError as err:
            pytest.fail(str(err))
