"""Point numba's on-disk cache at a folder keyed by the compiled modules' sources.

numba invalidates a cached function only when *its own* file changes, not when a
function it calls (in another module) does: after an edit to the tyre model, the cached
step loop in simulate.py would keep running the old tyre code. Keying the cache folder
by a digest of every module with compiled code makes any edit start a fresh cache. That
includes modules whose constants compiled code reads: numba freezes globals at compile time,
so tire.py (the ``I_<KEY>`` coefficient indices) is listed although it compiles nothing.
Must run before those modules are imported (sideslip_sim/__init__.py does it first).
A user's own NUMBA_CACHE_DIR is respected.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

COMPILED_MODULES = (
    "tire.py",
    "inline_math.py",
    "tire_forces.py",
    "dynamics.py",
    "driver.py",
    "simulate.py",
)


def configure() -> Path | None:
    if os.environ.get("NUMBA_CACHE_DIR"):
        return None
    from numba.core import config

    here = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for name in COMPILED_MODULES:
        digest.update((here / name).read_bytes())
    root = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    folder = root / "sideslip" / "numba" / digest.hexdigest()[:16]
    config.CACHE_DIR = str(folder)
    return folder
