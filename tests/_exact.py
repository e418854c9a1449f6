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


def angle_inside(lo: float, hi: float, v: mpmath.mpf, context: mpmath.MPContext = MP) -> bool:
    """Whether ``v + 2πk`` lies in [lo, hi] for some integer k, 2π taken in ``context``:
    pass the context ``v`` was computed in when it is more precise than this module's (a
    bearing computed at 4,400 bits may lie closer to a bound than 1,300 bits of 2π can
    tell)."""
    if not lo <= hi:
        return False
    if hi - lo >= 7.0:
        return True
    two_pi = 2 * context.pi
    k = context.ceil((context.mpf(float(lo)) - v) / two_pi)
    return v + k * two_pi <= context.mpf(float(hi))
