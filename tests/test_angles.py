"""cuikslam.interval.angles against the exact reference of the tests (tests/_exact.py)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from _exact import MP, TWO_PI, angle_inside, mpf
from cuikslam.interval.angles import (
    PI_HI,
    PI_LO,
    TWO_PI_HI,
    TWO_PI_LO,
    angle_excess,
    angle_in,
    angles_inside,
    out_of_view_arc,
    wrap_angle,
)

finite = st.floats(-1e4, 1e4, allow_nan=False)
near_turns = st.builds(
    lambda k, d: k * TWO_PI_LO + d, st.integers(-1000, 1000), st.floats(-1e-9, 1e-9)
)


def test_the_enclosures_of_pi_hold_pi() -> None:
    assert mpf(PI_LO) < MP.pi < mpf(PI_HI)
    assert mpf(TWO_PI_LO) < TWO_PI < mpf(TWO_PI_HI)
    # TWO_PI_EXACT: tests/test_truth.py::test_pi_enclosure_holds_pi_tightly


@given(lo=st.one_of(finite, near_turns), width=st.floats(0, 8), angle=st.one_of(finite, near_turns))
def test_angle_in_agrees_with_the_exact_reference(lo: float, width: float, angle: float) -> None:
    hi = lo + width
    assume(math.isfinite(hi))
    assert angle_in(lo, hi, angle) is angle_inside(lo, hi, mpf(angle))


@pytest.mark.parametrize(
    ("lo", "hi", "angle", "inside"),
    [
        (TWO_PI_LO, TWO_PI_HI, 0.0, True),  # 2π lies between its two float neighbours
        (TWO_PI_LO, TWO_PI_LO, 0.0, False),  # the float 2π is not 2π
        (-TWO_PI_HI, -TWO_PI_LO, 0.0, True),
        (1.0, 0.0, 0.5, False),  # empty
        (-math.inf, 0.0, 3.0, True),  # unbounded: any angle
        (-0.1, 0.1, Fraction(1, 10), True),  # the float 0.1 lies above 1/10
        (-0.1, 0.1, 0.1 + 2**-54, False),
    ],
)
def test_angle_in_decides_at_the_float_of_two_pi(lo, hi, angle, inside) -> None:
    assert angle_in(lo, hi, angle) is inside


@settings(deadline=None)  # the first example loads a compiled kernel
@given(
    lo=st.one_of(finite, near_turns),
    width=st.floats(0, 8),
    x0=st.one_of(finite, near_turns),
    x_width=st.floats(0, 8),
)
def test_angles_inside_proves_every_angle_of_the_interval_inside(
    lo: float, width: float, x0: float, x_width: float
) -> None:
    hi, x1 = lo + width, x0 + x_width
    assume(math.isfinite(hi) and math.isfinite(x1))
    inside = bool(angles_inside(np.array([[x0, x1]]), lo, hi)[0])
    if inside and width < 2 * math.pi:
        # one shift puts the whole interval in: both ends inside, no wider than [lo, hi]
        assert angle_inside(lo, hi, mpf(x0)) and angle_inside(lo, hi, mpf(x1))
        assert x1 - x0 <= hi - lo
    point = (lo + hi) / 2  # inside [lo, hi] itself: found
    assert angles_inside(np.array([[point, point]]), lo, hi)[0]


@given(value=finite, lo=finite, width=st.floats(0, 6))
def test_angle_excess_is_zero_inside_and_positive_outside(value, lo, width) -> None:
    hi = lo + width
    excess = angle_excess(value, lo, hi)
    assert excess >= 0.0
    if excess > 1e-9:  # the float remainder errs by far less than this
        assert not angle_inside(lo, hi, mpf(value))
    if excess == 0.0:
        assert angle_inside(lo - 1e-9, hi + 1e-9, mpf(value))


@settings(deadline=None)  # the first example loads a compiled kernel
@given(fov=st.floats(1e-6, 2 * math.pi, exclude_max=True))
def test_the_out_of_view_arcs_enclose_and_lie_inside_the_unseen_bearings(fov: float) -> None:
    half = mpf(fov) / 2
    outer = out_of_view_arc(fov)
    inner = out_of_view_arc(fov, inner=True)
    assert outer is not None and inner is not None
    # the unseen bearings are the open arc (half, 2π - half)
    assert mpf(outer[0]) <= half and TWO_PI - half <= mpf(outer[1])
    assert half < mpf(inner[0]) <= mpf(inner[1]) < TWO_PI - half


def test_a_sensor_that_sees_all_round_has_no_out_of_view_arc() -> None:
    assert out_of_view_arc(2 * math.pi) is None
    assert out_of_view_arc(7.0, inner=True) is None


@given(angle=st.floats(-1e3, 1e3))
def test_wrap_angle_lands_in_the_half_open_turn(angle: float) -> None:
    wrapped = wrap_angle(angle)
    assert -math.pi < wrapped <= math.pi
    turns = (angle - wrapped) / TWO_PI_LO
    assert abs(turns - round(turns)) < 1e-9


def test_wrap_angle_sends_minus_pi_to_pi() -> None:
    assert wrap_angle(-math.pi) == math.pi
    assert wrap_angle(0.0) == 0.0
