"""The user's paths → the bags they name (step 1 of :mod:`.dataset`), and the error every
dataset step raises."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path


class DatasetError(ValueError):
    """Bags that cannot make a dataset; the message names the path, bag or setting at fault."""


def _is_bag_dir(path: Path) -> bool:
    return path.is_dir() and (path / "metadata.yaml").is_file()


def _bags_in(path: Path) -> list[Path]:
    """Bags at ``path``: itself, or its .mcap files, or the bags one level below it."""
    if path.is_file() and path.name == "metadata.yaml":
        path = path.parent
    if path.is_file():
        return [path] if path.suffix == ".mcap" else []
    if _is_bag_dir(path):
        return [path]
    # A directory of bare .mcap files (or a bag directory whose metadata.yaml was lost:
    # read_bag reads each .mcap alone, and the run metadata is inside the .mcap too).
    found = sorted(path.glob("*.mcap"))
    for child in sorted(path.iterdir()):
        if _is_bag_dir(child):
            found.append(child)
        elif child.is_dir():
            found.extend(sorted(child.glob("*.mcap")))
    return found


def find_bags(paths: Sequence[str | Path]) -> list[Path]:
    """Resolve user paths to the bags they name, sorted and without duplicates.

    Each path is a rosbag2 directory (holding metadata.yaml), a bare ``.mcap`` file, a
    directory of bare ``.mcap`` files, or a folder holding such bags one level down (e.g.
    a ``sideslip-generate`` output with its index.json, which is ignored).

    Raises:
        DatasetError: a path does not exist or holds no bag (the message names it).
    """
    if isinstance(paths, str | Path):
        paths = [paths]
    bags: set[Path] = set()
    for raw in paths:
        path = Path(raw)
        if not path.exists():
            msg = f"{path}: no such file or directory (expected a bag or a folder of bags)"
            raise DatasetError(msg)
        found = _bags_in(path)
        if not found:
            msg = (
                f"{path}: holds no bag (expected a rosbag2 directory with metadata.yaml, "
                "an .mcap file, or a folder of them)"
            )
            raise DatasetError(msg)
        bags.update(p.resolve() for p in found)
    return sorted(bags)
