"""Floating-point helpers for the witness search that stay finite on any valid input.

A log may hold signed zeros (``[0.0, -0.0]`` is a valid interval), subnormal and huge
magnitudes, zero-width intervals and infinite boxes. The optimisers of the witness search
only *propose* points (:mod:`.verify` decides, in interval arithmetic), so here it is
enough that nothing overflows to inf or NaN, no -0.0 reaches a routine that checks signs,
and a midpoint or a random point of an interval lies inside it.
"""

from __future__ import annotations

import math

import numpy as np

from cuikslam.interval.midpoints import half_width, midpoint

__all__ = ["BIG", "cos_sin", "finite", "half_width", "midpoint", "uniform", "wrap_near"]

BIG = 1e100
"""Residuals and Jacobian entries are clipped to this magnitude (their squares, summed
over thousands of rows, stay finite)."""


def uniform(rng: np.random.Generator, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """A random point of each (finite) interval ``[lo, hi]``, inside it.

    ``numpy``'s ``uniform`` refuses ``[0.0, -0.0]`` (its width's sign bit is set) and
    overflows on ``[-1e308, 1e308]``; a convex combination does neither.
    """
    lo = np.asarray(lo, dtype=float) + 0.0
    hi = np.asarray(hi, dtype=float) + 0.0
    u = rng.random(np.shape(lo))
    with np.errstate(over="ignore", invalid="ignore"):
        p = lo * (1.0 - u) + hi * u
    p = np.where(np.isfinite(p), p, midpoint(lo, hi, 0.0))
    return np.minimum(np.maximum(p, lo), hi) + 0.0


def finite(values: np.ndarray, nan: float = BIG) -> np.ndarray:
    """``values`` with NaN replaced by ``nan`` and every entry clipped to ``[-BIG, BIG]``.

    An array already within the limits comes back as it is (not copied): two reductions
    cost less than the replacing copies, and Jacobians are millions of entries on real logs.
    """
    values = np.asarray(values, dtype=float)
    if values.size == 0 or (values.min() >= -BIG and values.max() <= BIG):  # NaN fails both
        return values
    out = np.nan_to_num(values, nan=nan, posinf=BIG, neginf=-BIG)  # a copy
    return np.clip(out, -BIG, BIG, out=out)


def cos_sin(angle: float) -> tuple[float, float]:
    """``(cos, sin)`` of a float angle; NaN for an infinite or NaN one (no exception)."""
    if not math.isfinite(angle):
        return math.nan, math.nan
    return math.cos(angle), math.sin(angle)


def wrap_near(value: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """The representative of ``value`` (mod 2 pi) nearest ``centre``."""
    return centre + np.remainder(value - centre + np.pi, 2 * np.pi) - np.pi
