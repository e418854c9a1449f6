"""Exact reference arithmetic shared by the soundness tests: a 1300-bit mpmath context.

1300 bits: the free floats may be subnormal next to 20.0, and derived values must not
round away their tiny parts (a bearing of -1 - 1e-102 is not -1), and t + 2πk stays exact
enough for |k| <= 1e10. A private context, so the precision leaks into no other test.
"""

from __future__ import annotations

import mpmath

MP = mpmath.MPContext()
MP.prec = 1300
TWO_PI = 2 * MP.pi


def mpf(x: float) -> mpmath.mpf:
    """A float, exactly, in the reference context."""
    return MP.mpf(float(x))


def angle_inside(lo: float, hi: float, v: mpmath.mpf) -> bool:
    """Whether ``v + 2πk`` lies in [lo, hi] for some integer k."""
    if not lo <= hi:
        return False
    if hi - lo >= 7.0:
        return True
    k = MP.ceil((mpf(lo) - v) / TWO_PI)
    return v + k * TWO_PI <= mpf(hi)
