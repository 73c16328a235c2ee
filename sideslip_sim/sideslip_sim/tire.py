"""Tyre parameters: the Magic Formula 5.2 coefficients of one tyre, read from a ``.tir`` file.

:class:`TireParams` holds the coefficients the force model uses, in SI units, checked for
range when built; :meth:`TireParams.coefficients` packs them into the float64 array that
the numba kernels of :mod:`sideslip_sim.tire_forces` take, indexed by the ``I_<KEY>``
constants here (their order is :data:`COEFFICIENT_KEYS`). :func:`load_tire` parses a file
once per process. The file format itself is read by :mod:`sideslip_sim.tir_file`; which
keys the model needs, their units and ranges are decided here.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sideslip_sim.tir_file import TirError, TirFile, parse_tir

__all__ = [
    "COEFFICIENT_KEYS",
    "DEFAULT_TIR",
    "N_COEFFICIENTS",
    "TireParams",
    "load_tire",
]

DEFAULT_TIR = Path(__file__).resolve().parent / "data" / "tires" / "pacejka2006_205_60R15.tir"

# Order of the packed coefficient array: (section, keys). The I_* constants below index it;
# tests check that they agree with this table.
_LAYOUT: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("VERTICAL", ("FNOMIN", "VERTICAL_STIFFNESS", "VERTICAL_DAMPING")),
    ("DIMENSION", ("UNLOADED_RADIUS",)),
    (
        "SCALING_COEFFICIENTS",
        (
            "LFZO", "LCX", "LMUX", "LEX", "LKX", "LHX", "LVX", "LCY", "LMUY", "LEY", "LKY",
            "LHY", "LVY", "LXAL", "LYKA", "LVYKA", "LSGKP", "LSGAL", "LMY",
        ),
    ),
    (
        "LONGITUDINAL_COEFFICIENTS",
        (
            "PCX1", "PDX1", "PDX2", "PEX1", "PEX2", "PEX3", "PEX4", "PKX1", "PKX2", "PKX3",
            "PHX1", "PHX2", "PVX1", "PVX2", "RBX1", "RBX2", "RCX1", "REX1", "REX2", "RHX1",
            "PTX1", "PTX2", "PTX3",
        ),
    ),
    (
        "LATERAL_COEFFICIENTS",
        (
            "PCY1", "PDY1", "PDY2", "PEY1", "PEY2", "PEY3", "PKY1", "PKY2", "PHY1", "PHY2",
            "PVY1", "PVY2", "RBY1", "RBY2", "RBY3", "RCY1", "REY1", "REY2", "RHY1", "RHY2",
            "RVY1", "RVY2", "RVY4", "RVY5", "RVY6", "PTY1", "PTY2",
        ),
    ),
    ("ROLLING_COEFFICIENTS", ("QSY1", "QSY2")),
)  # fmt: skip
COEFFICIENT_KEYS: tuple[str, ...] = tuple(key for _, keys in _LAYOUT for key in keys)
_SECTION_OF: dict[str, str] = {key: section for section, keys in _LAYOUT for key in keys}

# [VERTICAL], [DIMENSION]
I_FNOMIN = 0
I_VERTICAL_STIFFNESS = 1
I_VERTICAL_DAMPING = 2
I_UNLOADED_RADIUS = 3
# [SCALING_COEFFICIENTS]
I_LFZO = 4
I_LCX = 5
I_LMUX = 6
I_LEX = 7
I_LKX = 8
I_LHX = 9
I_LVX = 10
I_LCY = 11
I_LMUY = 12
I_LEY = 13
I_LKY = 14
I_LHY = 15
I_LVY = 16
I_LXAL = 17
I_LYKA = 18
I_LVYKA = 19
I_LSGKP = 20
I_LSGAL = 21
I_LMY = 22
# [LONGITUDINAL_COEFFICIENTS]
I_PCX1 = 23
I_PDX1 = 24
I_PDX2 = 25
I_PEX1 = 26
I_PEX2 = 27
I_PEX3 = 28
I_PEX4 = 29
I_PKX1 = 30
I_PKX2 = 31
I_PKX3 = 32
I_PHX1 = 33
I_PHX2 = 34
I_PVX1 = 35
I_PVX2 = 36
I_RBX1 = 37
I_RBX2 = 38
I_RCX1 = 39
I_REX1 = 40
I_REX2 = 41
I_RHX1 = 42
I_PTX1 = 43
I_PTX2 = 44
I_PTX3 = 45
# [LATERAL_COEFFICIENTS]
I_PCY1 = 46
I_PDY1 = 47
I_PDY2 = 48
I_PEY1 = 49
I_PEY2 = 50
I_PEY3 = 51
I_PKY1 = 52
I_PKY2 = 53
I_PHY1 = 54
I_PHY2 = 55
I_PVY1 = 56
I_PVY2 = 57
I_RBY1 = 58
I_RBY2 = 59
I_RBY3 = 60
I_RCY1 = 61
I_REY1 = 62
I_REY2 = 63
I_RHY1 = 64
I_RHY2 = 65
I_RVY1 = 66
I_RVY2 = 67
I_RVY4 = 68
I_RVY5 = 69
I_RVY6 = 70
I_PTY1 = 71
I_PTY2 = 72
# [ROLLING_COEFFICIENTS]
I_QSY1 = 73
I_QSY2 = 74
N_COEFFICIENTS = 75

# Value ranges beyond "finite". Positive: they divide or set the load scale. Shape factors
# C ≤ 2: a larger C makes the force change sign at large slip (and the sin/cos kernels of
# inline_math assume |C·atan| ≤ π). |PKX3|, |PTX3| ≤ 5 keeps exp(±P·dfz) inside the range
# of inline_math.poly_exp.
_POSITIVE = ("FNOMIN", "UNLOADED_RADIUS", "VERTICAL_STIFFNESS", "LFZO", "PKY2", "PTY2")
_SHAPE_FACTORS = ("PCX1", "PCY1", "RCX1", "RCY1")
_EXPONENTS = ("PKX3", "PTX3")
# Accepted spellings in [UNITS]; sideslip works in SI only.
_SI_UNITS = {
    "LENGTH": {"meter", "metre", "m"},
    "FORCE": {"newton", "n"},
    "ANGLE": {"radian", "radians", "rad"},
    "MASS": {"kg", "kilogram"},
    "TIME": {"second", "s", "sec"},
}


@dataclass(frozen=True)
class TireParams:
    """MF 5.2 coefficients of one tyre, in :data:`COEFFICIENT_KEYS` order (SI units).

    Build with :meth:`from_tir`; read a value with ``params["PKY1"]``.
    """

    source: str
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.values) != N_COEFFICIENTS:
            raise ValueError(f"{self.source}: expected {N_COEFFICIENTS} coefficients")
        for key, value in zip(COEFFICIENT_KEYS, self.values, strict=True):
            problem = _range_problem(key, value)
            if problem:
                raise ValueError(f"{self.source}: {key} = {value} {problem}")

    @classmethod
    def from_tir(cls, path: str | Path = DEFAULT_TIR) -> TireParams:
        """Read a ``.tir`` file; :class:`TirError` names the file and key on any problem."""
        return cls.from_tir_file(parse_tir(path))

    @classmethod
    def from_tir_file(cls, tir: TirFile) -> TireParams:
        """Pick the keys this model needs out of a parsed file and check them."""
        _check_units(tir)
        values = []
        for key in COEFFICIENT_KEYS:
            section = _SECTION_OF[key]
            value = tir.number(section, key)
            problem = _range_problem(key, value)
            if problem:
                raise TirError(
                    tir.path,
                    f"[{section}] {key} = {value} {problem}",
                    line=tir.lines.get((section, key)),
                    section=section,
                    key=key,
                )
            values.append(value)
        return cls(source=tir.path, values=tuple(values))

    def __getitem__(self, key: str) -> float:
        return self.values[COEFFICIENT_KEYS.index(key)]

    def with_values(self, **overrides: float) -> TireParams:
        """A copy with some coefficients replaced, e.g. ``with_values(LMUY=0.8)``."""
        unknown = sorted(set(overrides) - set(COEFFICIENT_KEYS))
        if unknown:
            raise KeyError(f"unknown tyre coefficient(s): {', '.join(unknown)}")
        values = tuple(
            float(overrides.get(k, v)) for k, v in zip(COEFFICIENT_KEYS, self.values, strict=True)
        )
        return TireParams(source=f"{self.source} (modified)", values=values)

    def coefficients(self) -> np.ndarray:
        """A fresh float64 array for the ``@njit`` functions; index with ``I_<KEY>``."""
        return np.array(self.values, dtype=np.float64)

    @property
    def fnomin_n(self) -> float:
        """Nominal wheel load FNOMIN [N]."""
        return self.values[I_FNOMIN]

    @property
    def unloaded_radius_m(self) -> float:
        """Free tyre radius R0 [m]."""
        return self.values[I_UNLOADED_RADIUS]

    @property
    def vertical_stiffness_n_per_m(self) -> float:
        return self.values[I_VERTICAL_STIFFNESS]

    @property
    def vertical_damping_ns_per_m(self) -> float:
        return self.values[I_VERTICAL_DAMPING]


def _range_problem(key: str, value: float) -> str | None:
    """What is wrong with this coefficient value, or None."""
    if not math.isfinite(value):
        return "must be a finite number"
    if key in _POSITIVE and not value > 0.0:
        return "must be > 0"
    if key in _SHAPE_FACTORS and not 0.0 < value <= 2.0:
        return "must be in (0, 2]"
    if key in _EXPONENTS and not -5.0 <= value <= 5.0:
        return "must be in [-5, 5]"
    return None


def _check_units(tir: TirFile) -> None:
    for key, accepted in _SI_UNITS.items():
        if not tir.has("UNITS", key):
            continue
        unit = tir.string("UNITS", key)
        if unit.strip().lower() not in accepted:
            raise TirError(
                tir.path,
                f"[UNITS] {key} = {unit!r} not supported (sideslip reads SI files only)",
                line=tir.lines.get(("UNITS", key)),
                section="UNITS",
                key=key,
            )


@functools.lru_cache(maxsize=16)
def load_tire(path: str) -> TireParams:
    """A tyre file, parsed once per process (a batch reads each file once)."""
    return TireParams.from_tir(Path(path))
