"""Backward projections (HC4-revise) never remove a solution, and are tight where they should be.

Soundness: real points satisfying the relation are drawn first (floats for the arguments,
the exact result computed with mpmath), then random intervals containing them; after the
backward projection every point must still be inside. Angles are unwrapped: an interval
such as ``[5.9, 6.6]`` or one wider than 2π is valid, and a point is "inside" an angle
interval when some ``point + 2πk`` is (for a finite input interval, the very
representative that was inside must stay inside, since narrowing never drops a solution).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from _exact import MP, TWO_PI, angle_inside, mpf
from cuikslam import interval as ia
from cuikslam.interval import _rounding as rnd

pytestmark = [
    pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning"),
    pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning"),
]


N = 400


def enclose(v: mpmath.mpf, exact: bool = True) -> tuple[float, float]:
    """The tightest float interval containing the real ``v``.

    With ``exact=False`` (``v`` is a rounded transcendental value), a ``v`` that happens to
    be a float is widened by one ulp, so the true value is inside too.
    """
    f = float(v)
    lo = f if mpf(f) <= v else math.nextafter(f, -math.inf)
    hi = f if mpf(f) >= v else math.nextafter(f, math.inf)
    if not exact and lo == hi:
        lo, hi = math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf)
    return lo, hi


def widen(bounds: tuple[float, float], below: float, above: float) -> np.ndarray:
    """``[lo - below, hi + above]``; rounding to nearest keeps the original interval inside."""
    lo, hi = bounds
    return np.array([lo - below, hi + above], dtype=np.float64)


def contains(box: np.ndarray, v: mpmath.mpf) -> bool:
    return box[0] <= box[1] and mpf(box[0]) <= v <= mpf(box[1])


def contains_angle(box: np.ndarray, v: mpmath.mpf) -> bool:
    """Whether ``v + 2πk`` lies in the box for some integer k."""
    return angle_inside(float(box[0]), float(box[1]), v)


def angle_kept(before: np.ndarray, after: np.ndarray, v: mpmath.mpf) -> bool:
    """The representative ``v`` of a finite interval stays; otherwise some congruent value does."""
    if math.isfinite(before[0]) and math.isfinite(before[1]):
        return contains(after, v)
    return contains_angle(after, v)


# ---------------------------------------------------------------- strategies

values = st.one_of(
    st.floats(min_value=-1e6, max_value=1e6, allow_nan=False),
    st.floats(min_value=-10.0, max_value=10.0, allow_nan=False),
    st.floats(min_value=-1e-200, max_value=1e-200, allow_nan=False, allow_subnormal=True),
    st.sampled_from([0.0, -0.0, 1.0, -1.0, 5e-324]),
    st.floats(min_value=-1e100, max_value=1e100, allow_nan=False),
)
margins = st.one_of(
    st.just(0.0),
    st.floats(min_value=0.0, max_value=1e-12),
    st.floats(min_value=0.0, max_value=1.0),
    st.floats(min_value=0.0, max_value=100.0),
    st.just(math.inf),
)
angle_points = st.one_of(
    st.floats(min_value=-math.pi, max_value=math.pi),
    st.sampled_from(
        [0.0, math.pi, -math.pi, math.pi / 2, -math.pi / 2, rnd.PI_HI, -rnd.PI_HI, 1e-300]
    ),
    st.builds(
        lambda c, d: c + d,
        st.sampled_from([0.0, math.pi, -math.pi, math.pi / 2, -math.pi / 2]),
        st.floats(min_value=-1e-6, max_value=1e-6),
    ),
)
turns = st.one_of(st.integers(-3, 3), st.integers(-(10**6), 10**6), st.integers(-(10**10), 10**10))
angle_margins = st.one_of(
    st.just(0.0),
    st.floats(min_value=0.0, max_value=1e-9),
    st.floats(min_value=0.0, max_value=0.5),
    st.floats(min_value=0.0, max_value=8.0),  # intervals wider than 2π
    st.just(math.inf),
)


# ---------------------------------------------------------------- arithmetic

BINARY = {
    "add": (ia.bwd_add, lambda a, b: a + b),
    "sub": (ia.bwd_sub, lambda a, b: a - b),
    "mul": (ia.bwd_mul, lambda a, b: a * b),
}


@settings(max_examples=2 * N, deadline=None)
@given(
    name=st.sampled_from(sorted(BINARY)),
    x=values,
    y=values,
    m=st.lists(margins, min_size=6, max_size=6),
)
@example(name="mul", x=0.0, y=3.0, m=[0.0, 1.0, 0.0, 0.0, 1.0, 1.0])
@example(name="mul", x=2.0, y=0.0, m=[0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
@example(name="add", x=15.0, y=0.0, m=[0.0] * 6)
def test_bwd_binary_keeps_solutions(name, x, y, m):
    op, f = BINARY[name]
    with MP.workprec(2400):
        z = f(mpf(x), mpf(y))
    zb = widen(enclose(z), m[0], m[1])
    xb = widen((x, x), m[2], m[3])
    yb = widen((y, y), m[4], m[5])
    x2, y2 = op(zb, xb, yb)
    assert contains(x2, mpf(x)), (name, zb, xb, yb, x2)
    assert contains(y2, mpf(y)), (name, zb, xb, yb, y2)
    # contractance
    assert xb[0] <= x2[0] and x2[1] <= xb[1]
    assert yb[0] <= y2[0] and y2[1] <= yb[1]


@settings(max_examples=N, deadline=None)
@given(x=values, m=st.lists(margins, min_size=4, max_size=4))
@example(x=-3.0, m=[0.0, 0.0, 0.0, 10.0])
@example(x=1e-170, m=[0.0, 0.0, 0.0, 0.0])
def test_bwd_sqr_keeps_solutions(x, m):
    z = mpf(x) ** 2
    zb = widen(enclose(z), m[0], m[1])
    xb = widen((x, x), m[2], m[3])
    x2 = ia.bwd_sqr(zb, xb)
    assert contains(x2, mpf(x)), (zb, xb, x2)
    assert xb[0] <= x2[0] and x2[1] <= xb[1]


@settings(max_examples=N, deadline=None)
@given(x=values.map(abs), m=st.lists(margins, min_size=4, max_size=4))
def test_bwd_sqrt_keeps_solutions(x, m):
    z = MP.sqrt(mpf(x))
    zb = widen(enclose(z, exact=False), m[0], m[1])
    xb = widen((x, x), m[2], m[3])
    x2 = ia.bwd_sqrt(zb, xb)
    assert contains(x2, mpf(x)), (zb, xb, x2)


def iv(lo: float, hi: float) -> np.ndarray:
    return np.array([lo, hi], dtype=np.float64)


def test_bwd_arithmetic_tightness():
    x, y = ia.bwd_add(iv(1, 2), iv(0, 10), iv(0, 0.5))
    assert x.tolist() == [0.5, 2.0] and y.tolist() == [0.0, 0.5]
    x, y = ia.bwd_sub(iv(1, 2), iv(0, 10), iv(0, 0.5))
    assert x.tolist() == [1.0, 2.5] and y.tolist() == [0.0, 0.5]
    x, y = ia.bwd_mul(iv(1, 2), iv(-10, 10), iv(1, 2))
    assert x == pytest.approx([0.5, 2.0], abs=1e-15) and y.tolist() == [1.0, 2.0]
    assert ia.bwd_sqr(iv(1, 4), iv(-10, 10)) == pytest.approx([-2.0, 2.0], abs=1e-15)
    assert ia.bwd_sqr(iv(1, 4), iv(0, 10)) == pytest.approx([1.0, 2.0], abs=1e-15)
    assert ia.bwd_sqr(iv(1, 4), iv(-10, -1.5)) == pytest.approx([-2.0, -1.5], abs=1e-15)
    assert ia.bwd_sqrt(iv(1, 2), iv(-5, 10)) == pytest.approx([1.0, 4.0], abs=1e-15)
    # no solution: proofs
    assert ia.is_empty(ia.bwd_sqr(iv(1, 4), iv(2.5, 10)))
    assert ia.is_empty(ia.bwd_mul(iv(1, 2), iv(-1, 1), iv(0, 0))[0])
    assert ia.is_empty(ia.bwd_add(iv(1, 2), iv(0, 0.5), iv(0, 0.25))[0])


# ---------------------------------------------------------------- angles


def angle_box(t: mpmath.mpf, k: int, below: float, above: float) -> np.ndarray:
    """An unwrapped interval containing the representative ``t + 2πk``."""
    return widen(enclose(t + k * TWO_PI, exact=False), below, above)


@settings(max_examples=2 * N, deadline=None)
@given(
    t=angle_points,
    k=turns,
    name=st.sampled_from(["cos", "sin"]),
    m=st.lists(angle_margins, min_size=2, max_size=2),
    mz=st.lists(st.one_of(st.just(0.0), st.floats(0.0, 0.3), st.just(2.0)), min_size=2, max_size=2),
)
@example(t=0.3, k=1, name="cos", m=[0.0, 0.0], mz=[0.0, 0.0])
@example(t=math.pi, k=0, name="cos", m=[0.1, 0.15], mz=[0.0, 0.0])  # straddles ±π
@example(t=-math.pi, k=3, name="sin", m=[0.2, 0.1], mz=[0.0, 0.0])
@example(t=0.0, k=1, name="cos", m=[0.383, 0.317], mz=[0.0, 0.0])  # ~[5.9, 6.6]
@example(t=math.pi / 2, k=0, name="sin", m=[0.0, 0.0], mz=[0.0, 0.0])
def test_bwd_cos_sin_keep_solutions(t, k, name, m, mz):
    tm = mpf(t)
    z = MP.cos(tm) if name == "cos" else MP.sin(tm)
    zb = widen(enclose(z, exact=False), mz[0], mz[1])
    xb = angle_box(tm, k, m[0], m[1])
    op = ia.bwd_cos if name == "cos" else ia.bwd_sin
    x2 = op(zb, xb)
    assert angle_kept(xb, x2, tm + k * TWO_PI), (name, t, k, zb, xb, x2)
    assert ia.is_empty(x2) or xb[0] <= x2[0] <= x2[1] <= xb[1]


@settings(max_examples=2 * N, deadline=None)
@given(
    t=angle_points,
    k=turns,
    j=st.integers(-3, 3),
    m=st.lists(angle_margins, min_size=4, max_size=4),
)
@example(t=0.0, k=1, j=0, m=[0.383, 0.317, 0.1, 0.1])  # [5.9, 6.6] ∩ [-0.1, 0.1] + 2πZ
@example(t=math.pi, k=0, j=-1, m=[0.1, 0.1, 0.0, 0.0])
def test_periodic_intersect_keeps_solutions(t, k, j, m):
    """x ≡ a (mod 2π) with x = t + 2πk in X and a = t + 2πj in A: x stays in X ∩ (A + 2πZ)."""
    tm = mpf(t)
    xb = angle_box(tm, k, m[0], m[1])
    ab = angle_box(tm, j, m[2], m[3])
    assume(np.all(np.isfinite(ab)))
    out = ia.periodic_intersect(xb, ab)
    assert angle_kept(xb, out, tm + k * TWO_PI), (t, k, j, xb, ab, out)


def test_angle_tightness():
    acos_half = math.acos(0.5)
    assert ia.bwd_cos(iv(0.5, 1), iv(-4, 4)) == pytest.approx([-acos_half, acos_half], abs=1e-12)
    assert ia.bwd_sin(iv(0.5, 1), iv(-3, 4)) == pytest.approx(
        [math.pi / 6, 5 * math.pi / 6], abs=1e-12
    )
    # unwrapped: near 2π, no loss at the cut
    a = math.acos(0.99)
    assert ia.bwd_cos(iv(0.99, 1), iv(5.9, 6.6)) == pytest.approx(
        [2 * math.pi - a, 2 * math.pi + a], abs=1e-12
    )
    # straddling ±π: cos near -1
    a = math.pi - math.acos(-0.999)
    assert ia.bwd_cos(iv(-1, -0.999), iv(3, 3.3)) == pytest.approx(
        [math.pi - a, math.pi + a], abs=1e-12
    )
    assert ia.periodic_intersect(iv(5.9, 6.6), iv(-0.1, 0.1)) == pytest.approx(
        [2 * math.pi - 0.1, 2 * math.pi + 0.1], abs=1e-12
    )
    assert ia.periodic_intersect(iv(-10, 10), iv(3, 3.2)) == pytest.approx(
        [3 - 4 * math.pi, 3.2 + 2 * math.pi], abs=1e-12
    )
    assert ia.is_empty(ia.periodic_intersect(iv(0.5, 1), iv(2, 3)))
    assert ia.is_empty(ia.bwd_cos(iv(0.9, 1), iv(2, 4)))
    # "any angle": unchanged
    assert ia.periodic_intersect(iv(0.5, 1), iv(0, 7)).tolist() == [0.5, 1.0]


# ---------------------------------------------------------------- angle_of (atan2 without the cut)

coords = st.one_of(
    st.floats(min_value=-100.0, max_value=100.0),
    st.floats(min_value=-1e-3, max_value=1e-3),
    st.sampled_from([0.0, 1.0, -1.0, 1e-300, -1e-300]),
)
coord_margins = st.one_of(
    st.just(0.0),
    st.floats(min_value=0.0, max_value=1e-9),
    st.floats(min_value=0.0, max_value=1.0),
    st.floats(min_value=0.0, max_value=50.0),
)


@settings(max_examples=3 * N, deadline=None)
@given(
    px=coords,
    py=coords,
    k=turns,
    m=st.lists(coord_margins, min_size=4, max_size=4),
    mt=st.lists(angle_margins, min_size=2, max_size=2),
)
@example(px=-1.5, py=0.0, k=0, m=[0.5, 0.5, 0.1, 0.1], mt=[0.14, 0.16])  # left, theta [3, 3.3]
@example(px=-1.5, py=-0.05, k=-1, m=[0.5, 0.5, 0.05, 0.15], mt=[0.5, 0.5])
@example(px=-1.0, py=1e-300, k=0, m=[0.0, 0.0, 0.0, 0.0], mt=[0.0, 0.0])
@example(px=-1.0, py=-1e-300, k=0, m=[0.0, 0.0, 0.0, 0.0], mt=[0.0, 0.0])
@example(px=0.0, py=-2.0, k=5, m=[1.0, 1.0, 0.0, 0.0], mt=[0.0, 0.0])
def test_angle_of_keeps_solutions(px, py, k, m, mt):
    assume(px != 0.0 or py != 0.0)
    t = MP.atan2(mpf(py), mpf(px))
    xb = widen((px, px), m[0], m[1])
    yb = widen((py, py), m[2], m[3])
    tb = angle_box(t, k, mt[0], mt[1])
    y2, x2, t2 = ia.angle_of(yb, xb, tb)
    assert contains(x2, mpf(px)), (xb, yb, tb, x2, y2, t2)
    assert contains(y2, mpf(py)), (xb, yb, tb, x2, y2, t2)
    assert angle_kept(tb, t2, t + k * TWO_PI), (xb, yb, tb, x2, y2, t2)
    for before, after in ((xb, x2), (yb, y2)):
        assert before[0] <= after[0] and after[1] <= before[1]


def test_angle_of_has_no_cut():
    # box left of the origin straddling the x-axis: angles π ± atan(0.1)
    y, x, t = ia.angle_of(iv(-0.1, 0.1), iv(-2.0, -1.0), iv(3.0, 3.3))
    half = math.atan(0.1)
    assert t == pytest.approx([math.pi - half, math.pi + half], abs=1e-12)
    assert y.tolist() == [-0.1, 0.1] and x.tolist() == [-2.0, -1.0]
    # same with theta given around -π: the copy there
    _, _, t = ia.angle_of(iv(-0.1, 0.1), iv(-2.0, -1.0), iv(-3.3, -3.0))
    assert t == pytest.approx([-math.pi - half, -math.pi + half], abs=1e-12)
    # and the box narrows to the angles left: y = x tan(theta) with theta in [3.1, 3.2]
    y, x, t = ia.angle_of(iv(-0.1, 0.1), iv(-2.0, -1.0), iv(3.1, 3.2))
    assert y == pytest.approx([-0.1, -2.0 * math.tan(3.1)], abs=1e-12)
    assert x.tolist() == [-2.0, -1.0]
    assert t.tolist() == [3.1, 3.2]
    # no solution: the box lies left, theta points right
    y, x, t = ia.angle_of(iv(-0.1, 0.1), iv(-2.0, -1.0), iv(-0.5, 0.5))
    assert ia.is_empty(y) and ia.is_empty(x) and ia.is_empty(t)


def test_atan2_principal_straddling_cut():
    # the classic atan2 cannot do better than [-π, π] there
    out = ia.atan2(iv(-0.1, 0.1), iv(-2.0, -1.0))
    assert out[0] <= -math.pi + math.atan(0.1) and out[1] >= math.pi - math.atan(0.1)


def _signed(box, signs):
    """The box with each zero bound given the sign drawn for it (an interval's zero has none)."""
    return iv(*(math.copysign(0.0, -1.0 if s else 1.0) if b == 0.0 else b
                for b, s in zip(box, signs, strict=True)))  # fmt: skip


@settings(max_examples=3 * N, deadline=None)
@given(
    px=st.sampled_from([0.0, 1.0, -1.0, 1e-310, -5e-324]),
    py=st.sampled_from([0.0, 2.0, -2.0, 1e-310, -5e-324]),
    k=turns,
    m=st.lists(st.sampled_from([0.0, 1e-310, 1.0]), min_size=4, max_size=4),
    signs=st.lists(st.booleans(), min_size=4, max_size=4),
)
@example(px=0.0, py=1e-310, k=0, m=[0.0, 0.0, 0.0, 0.0], signs=[False, True, False, False])
def test_angle_of_keeps_solutions_with_signed_zero_bounds(px, py, k, m, signs):
    """A bound of -0.0 is the same bound as +0.0: ``[0.0, -0.0]`` holds x = 0. atan2 reads
    the sign of a zero (atan2(0, -0) = pi), which once lost the +y axis' angle pi/2."""
    assume(px != 0.0 or py != 0.0)
    t = MP.atan2(mpf(py), mpf(px))
    xb = _signed(widen((px, px), m[0], m[1]), signs[:2])
    yb = _signed(widen((py, py), m[2], m[3]), signs[2:])
    tb = angle_box(t, k, 0.0, 0.0)
    y2, x2, t2 = ia.angle_of(yb, xb, tb)
    assert contains(x2, mpf(px)), (xb, yb, tb, x2, y2, t2)
    assert contains(y2, mpf(py)), (xb, yb, tb, x2, y2, t2)
    assert angle_kept(tb, t2, t + k * TWO_PI), (xb, yb, tb, x2, y2, t2)
