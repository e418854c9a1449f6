"""Midpoints and half-widths of float intervals, in plain NumPy (nothing compiled).

A log may hold signed zeros, subnormal and huge magnitudes, zero-width intervals and
infinite boxes: these stay finite and inside the interval on any valid input, where
``(lo + hi) / 2`` overflows for huge bounds and ``lo / 2 + hi / 2`` can fall outside a
subnormal interval. Used where a point of an interval is proposed (the witness search) or
reported (the box centres and the Gaussians of :mod:`cuikslam.interop`).

Examples
--------
>>> midpoint(np.array([1.0, -1e308, 0.0]), np.array([2.0, 1e308, np.inf])).tolist()
[1.5, 0.0, nan]
>>> half_width(np.array([0.9, -1e308]), np.array([1.1, 1e308])).tolist()
[0.10000000000000003, 1e+308]
"""

from __future__ import annotations

import numpy as np

__all__ = ["half_width", "midpoint"]


def midpoint(lo: np.ndarray, hi: np.ndarray, default: float = np.nan) -> np.ndarray:
    """The midpoint of each interval ``[lo, hi]``, inside it, without overflow.

    ``default`` where a bound is not finite. ``(lo + hi) / 2`` overflows for huge bounds,
    and ``lo / 2 + hi / 2`` can fall outside a subnormal interval; this does neither.
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    finite = np.isfinite(lo) & np.isfinite(hi)
    with np.errstate(over="ignore", invalid="ignore"):
        width = hi - lo
        mid = np.where(np.isfinite(width), lo + width / 2.0, lo / 2.0 + hi / 2.0)
        mid = np.minimum(np.maximum(mid, lo), hi)
    return np.where(finite, mid + 0.0, default)


def half_width(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Half the width of each interval, without overflow (inf for an unbounded interval)."""
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        width = hi - lo
        half = np.where(np.isfinite(width), width / 2.0, hi / 2.0 - lo / 2.0)
    return np.maximum(half, 0.0) + 0.0
