"""Fit the rational tanh of ``sideslip_estimator.lstm_kernel`` and print its error.

tanh(x) ≈ x·P(x²)/Q(x²) on [0, clamp] (odd, so the negative half follows), Q's constant
term 1. A linearised weighted least-squares fit (x·P − tanh·Q = tanh·(Q − 1) solved for
the coefficients), its weights raised where the error is large (a Lawson-style
iteration towards equal ripple), in the variable u = x²/clamp² so the system stays
well conditioned. Run: ``.venv/bin/python bench/tools/fit_tanh.py [--clamp 10]
[--numerator 6] [--denominator 5]``; paste the printed tuples into lstm_kernel.py.
"""

from __future__ import annotations

import argparse

import numpy as np


def fit(
    clamp: float, numerator: int, denominator: int, rounds: int = 60
) -> tuple[np.ndarray, np.ndarray]:
    """P (``numerator`` terms) and Q (``denominator`` terms, Q[0] = 1) in powers of x²."""
    x = np.linspace(1e-6, clamp, 40_001)
    scale = clamp * clamp
    u = x * x / scale
    y = np.tanh(x)
    a = np.concatenate(
        [
            x[:, None] * u[:, None] ** np.arange(numerator),
            -y[:, None] * u[:, None] ** np.arange(1, denominator),
        ],
        axis=1,
    )
    weight = np.ones_like(x)
    for _ in range(rounds):
        solution, *_ = np.linalg.lstsq(a * weight[:, None], y * weight, rcond=None)
        p = solution[:numerator] / scale ** np.arange(numerator)
        q = np.concatenate([[1.0], solution[numerator:]]) / scale ** np.arange(denominator)
        error = np.abs(evaluate(p, q, x, clamp) - y)
        weight *= (error / error.mean()) ** 0.3
        weight /= weight.mean()
    return p, q


def evaluate(p: np.ndarray, q: np.ndarray, x: np.ndarray, clamp: float) -> np.ndarray:
    """x·P(x²)/Q(x²) in float64 with x clamped to ±clamp (Horner, as the kernel does)."""
    x = np.clip(x, -clamp, clamp)
    t = x * x
    num = np.zeros_like(x)
    den = np.zeros_like(x)
    for c in p[::-1]:
        num = num * t + c
    for c in q[::-1]:
        den = den * t + c
    return x * num / den


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clamp", type=float, default=10.0)
    parser.add_argument("--numerator", type=int, default=6)
    parser.add_argument("--denominator", type=int, default=5)
    args = parser.parse_args()
    p, q = fit(args.clamp, args.numerator, args.denominator)
    grid = np.linspace(-2 * args.clamp, 2 * args.clamp, 2_000_001)
    error = np.abs(evaluate(p, q, grid, args.clamp) - np.tanh(grid))
    print(f"TANH_P = {tuple(float(c) for c in p)}")
    print(f"TANH_Q = {tuple(float(c) for c in q)}")
    print(f"max |error| over [-{2 * args.clamp}, {2 * args.clamp}] in float64: {error.max():.3g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
