"""Angles modulo 2π outside compiled code: the constants of π, exact containment, view arcs.

The compiled narrowing of angles is :mod:`cuikslam.interval._periodic`; this module holds
what the rest of the library asks of an angle in plain Python, in one place:

- the float enclosures of π, π/2 and 2π every kernel uses (``PI_LO < π < PI_HI``);
- :func:`angle_in`: whether a true angle, modulo an exact 2π, lies in a float interval
  (the truth checks of results and benchmarks);
- :func:`angles_inside`: whether angle *intervals* lie, modulo 2π, inside float intervals,
  rigorously (a True is a proof: the verification of witnesses);
- :func:`angle_excess`: how far an angle lies outside an interval, modulo 2π (a
  diagnostic, in floats);
- :func:`wrap_angle`: a float angle's representative in (-π, π] (simulation, data);
- :func:`out_of_view_arc`: the bearings a sensor of a given field of view cannot see.

It imports no compiled code, so reading results stays light.

Examples
--------
>>> from fractions import Fraction
>>> angle_in(6.0, 6.5, 0.0)  # 2π lies in [6.0, 6.5]
True
>>> angle_in(-0.1, 0.1, Fraction(1, 10))  # the float 0.1 is above 1/10, so 1/10 is inside
True
>>> angle_in(-0.1, 0.1, 0.1 + 2**-54)
False
"""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

__all__ = [
    "HALF_PI_HI",
    "HALF_PI_LO",
    "PI_HI",
    "PI_LO",
    "TWO_PI_EXACT",
    "TWO_PI_HI",
    "TWO_PI_LO",
    "angle_excess",
    "angle_in",
    "angles_inside",
    "out_of_view_arc",
    "wrap_angle",
]

PI_LO = math.pi  # the double nearest pi lies below pi
PI_HI = float(np.nextafter(math.pi, math.inf))
HALF_PI_LO = PI_LO / 2.0
HALF_PI_HI = PI_HI / 2.0
TWO_PI_LO = PI_LO * 2.0
TWO_PI_HI = PI_HI * 2.0


def _pi_enclosure(digits: int = 420) -> tuple[Fraction, Fraction]:
    """Rationals ``lo < π < hi`` less than ``10**(10 - digits)`` apart (Machin's formula).

    Fixed point with ``digits + 10`` decimals: each truncated term errs by at most one unit,
    and fewer than ``digits`` terms are summed, so the sum errs by far less than 10**6 units.
    """
    unit = 10 ** (digits + 10)

    def arctan_inverse(x: int) -> int:
        total = term = unit // x
        n, sign = 1, 1
        while term:
            term //= x * x
            n += 2
            sign = -sign
            total += sign * (term // n)
        return total

    approx = 4 * (4 * arctan_inverse(5) - arctan_inverse(239))
    return Fraction(approx - 10**6, unit), Fraction(approx + 10**6, unit)


_PI_EXACT = _pi_enclosure()
TWO_PI_EXACT: tuple[Fraction, Fraction] = (2 * _PI_EXACT[0], 2 * _PI_EXACT[1])
"""Rationals enclosing 2π, less than 1e-409 apart."""


def angle_in(lo: float, hi: float, angle: Fraction | float | int) -> bool:
    """Whether ``angle + 2πk`` lies in the float interval ``[lo, hi]`` for some integer k,
    decided exactly.

    Parameters
    ----------
    lo, hi : float
        The interval (unwrapped; empty when ``lo > hi``, any angle when infinite).
    angle : Fraction, float or int
        The angle, taken exactly (a float is its exact binary value).

    Returns
    -------
    bool
        True when some copy of ``angle`` lies in the interval.

    Notes
    -----
    2π is known between two rationals 1e-409 apart; a k for which that enclosure does not
    decide containment would need ``angle + 2πk`` within 1e-400 of a float bound, which
    for k != 0 (2πk irrational) no float-sized angle comes near.
    """
    lo, hi = float(lo), float(hi)
    if not lo <= hi:
        return False
    if math.isinf(lo) or math.isinf(hi):
        return True  # unbounded: holds every angle
    angle = Fraction(angle)
    two_pi_lo, two_pi_hi = TWO_PI_EXACT
    flo, fhi = Fraction(lo), Fraction(hi)
    if fhi - flo >= two_pi_hi:
        return True
    # the least k with angle + 2πk >= lo lies between these two (2π in [LO, HI])
    ks = sorted({math.ceil((flo - angle) / two_pi_lo), math.ceil((flo - angle) / two_pi_hi)})
    for k in range(ks[0] - 1, ks[-1] + 1):
        low, high = angle + k * two_pi_lo, angle + k * two_pi_hi
        if k < 0:
            low, high = high, low
        if flo <= low and high <= fhi:
            return True
    return False


def angles_inside(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Where the angle interval ``x`` lies inside ``[lo, hi] + 2πk`` for one integer k.

    Parameters
    ----------
    x : ndarray, shape (..., 2)
        Angle intervals (unwrapped).
    lo, hi : ndarray or float
        The intervals to lie in, broadcast to ``x.shape[:-1]`` (any angle when ``hi - lo``
        may reach 2π).

    Returns
    -------
    ndarray of bool
        True where ``x`` is proven inside (the shift ``2πk`` is an outward-rounded
        enclosure, so a True is rigorous); False where it may not be, and for NaN or empty
        ``x``.

    Examples
    --------
    >>> angles_inside(np.array([[6.0, 6.5], [0.5, 0.7], [0.5, 0.6]]), -0.5, 0.6).tolist()
    [True, False, True]
    """
    from cuikslam.interval import ops as ia  # compiled: loaded only for this

    x = np.asarray(x, dtype=float)
    lo = np.broadcast_to(np.asarray(lo, dtype=float), x.shape[:-1])
    hi = np.broadcast_to(np.asarray(hi, dtype=float), x.shape[:-1])
    # bounds near 1e308 overflow to inf (outward, as they should); a NaN compares False
    with np.errstate(invalid="ignore", over="ignore"):
        width = ia.sub(ia.interval(hi), ia.interval(lo))[..., 0]
        any_angle = width >= TWO_PI_HI
        k = np.round(((lo + hi) / 2.0 - (x[..., 0] + x[..., 1]) / 2.0) / (2 * math.pi))
        k = np.where(np.isfinite(k), k, 0.0)
        two_pi = ia.interval(TWO_PI_LO, TWO_PI_HI)
        ok = np.zeros(x.shape[:-1], dtype=bool)
        for step in (0.0, -1.0, 1.0):
            shifted = ia.add(x, ia.mul(ia.interval(k + step), two_pi))
            ok |= (
                (shifted[..., 0] >= lo)
                & (shifted[..., 1] <= hi)
                & (shifted[..., 0] <= shifted[..., 1])
            )
    return (ok | any_angle) & (x[..., 0] <= x[..., 1])


def angle_excess(value: float, lo: float, hi: float) -> float:
    """How far the angle ``value`` (modulo 2π) lies outside ``[lo, hi]``; 0 inside.

    A diagnostic in floats (the copy of ``value`` at or above ``lo`` is found with a float
    remainder): use :func:`angle_in` to decide containment.
    """
    shifted = lo + (value - lo) % (2 * math.pi)
    if shifted <= hi:
        return 0.0
    return min(shifted - hi, lo + 2 * math.pi - shifted)


def wrap_angle(angle: float) -> float:
    """``angle`` wrapped to (−π, π] (in floats: for simulated and recorded values, not for
    bounds)."""
    wrapped = math.remainder(angle, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


def out_of_view_arc(fov: float, *, inner: bool = False) -> tuple[float, float] | None:
    """The bearings a sensor with field of view ``fov`` (centred on the heading) cannot see.

    Those are the open arc ``(fov / 2, 2π - fov / 2)``.

    Parameters
    ----------
    fov : float
        Field of view in radians; at least 2π sees every bearing.
    inner : bool
        False (default): a closed float interval containing the whole arc (what a
        constraint "this landmark is out of view" may assume). True: one contained in it
        (a bearing inside it is proven out of view).

    Returns
    -------
    tuple of float, or None
        ``(lo, hi)``; None when the sensor sees every bearing.
    """
    if fov >= 2 * math.pi:
        return None
    half = fov / 2.0
    if not inner:
        return float(np.nextafter(half, 0.0)), float(np.nextafter(TWO_PI_HI - half, math.inf))
    from cuikslam.interval._rounding import sub_down  # compiled: loaded only for this

    # a float below 2π - half, then one more step inside
    before = float(np.nextafter(sub_down(TWO_PI_LO, half), -math.inf))
    return float(np.nextafter(half, math.inf)), before
