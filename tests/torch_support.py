"""Torch's thread count for the tests that fine-tune and score real models."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator


@contextlib.contextmanager
def every_core() -> Iterator[int]:
    """Torch on every core this process may use while the block runs, then as before.

    Several test modules pin torch to one thread when imported (small models, where
    threads cost more than they give), and pytest imports them all before the first test,
    so the whole suite would run on one thread; the few tests that fine-tune and score a
    shipped model on minutes of driving are a large share of its time, with the second
    core idle. Yields the thread count."""
    import torch

    before = torch.get_num_threads()
    cores = len(os.sched_getaffinity(0))
    torch.set_num_threads(cores)
    try:
        yield cores
    finally:
        torch.set_num_threads(before)
