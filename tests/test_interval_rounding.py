"""Forward interval operations enclose the exact result, checked against mpmath.

Every operation of :mod:`cuikslam.interval` is evaluated on random intervals; points
sampled inside the inputs (endpoints included) are pushed through the exact function in
multi-precision arithmetic (``mpmath.mpf(float)`` is the exact binary value of the float),
and the float interval returned must contain each exact value. The strategies favour the
places where rounding goes wrong: near 0, ±π/2, ±π, multiples of 2π, huge and tiny
(subnormal) magnitudes.
"""

from __future__ import annotations

import importlib
import inspect
import math
import pkgutil
import re
from pathlib import Path

import mpmath
import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from numba.core.registry import CPUDispatcher
from numba.np.ufunc.gufunc import GUFunc

import cuikslam
from cuikslam import _jit
from cuikslam import interval as ia
from cuikslam._fpu import rounds_to_nearest
from cuikslam.interval import _rounding as rnd

# Huge and tiny inputs overflow inside the kernels, by design (the bounds then become MAX
# or inf, and TwoSum's error term NaN, which counts as inexact); numpy reports the flags.
pytestmark = [
    pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning"),
    pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning"),
]


PREC = 200
MAX = float(np.finfo(np.float64).max)
TINY = 5e-324
ULP_MAX = 2.0**971
N = 300  # examples per property

# ---------------------------------------------------------------- exact arithmetic


def mpf(x: float) -> mpmath.mpf:
    """The exact value of a double."""
    return mpmath.mpf(float(x))


def prec_for(*values: float) -> int:
    """Enough bits to reduce these values modulo 2π to 200 good bits."""
    e = max((math.frexp(v)[1] for v in values if math.isfinite(v) and v != 0.0), default=0)
    return PREC + max(0, e)


def inside(iv: np.ndarray, exact: mpmath.mpf) -> bool:
    lo, hi = float(iv[0]), float(iv[1])
    return lo <= hi and mpf(lo) <= exact <= mpf(hi)


def iv(lo: float, hi: float) -> np.ndarray:
    return np.array([lo, hi], dtype=np.float64)


# ---------------------------------------------------------------- strategies


def _nudge(x: float, steps: int) -> float:
    """``x`` moved by ``steps`` ulps, staying finite."""
    for _ in range(abs(steps)):
        x = math.nextafter(x, math.inf if steps > 0 else -math.inf)
    return min(max(x, -MAX), MAX)


signs = st.sampled_from([1.0, -1.0])
any_finite = st.floats(allow_nan=False, allow_infinity=False)
moderate = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False)
tiny = st.one_of(
    st.floats(min_value=-1e-290, max_value=1e-290, allow_nan=False, allow_subnormal=True),
    st.sampled_from([TINY, -TINY, 2.2250738585072014e-308, -2.2250738585072014e-308, 0.0, -0.0]),
)
huge = st.builds(
    lambda s, m: s * m,
    signs,
    st.one_of(
        st.floats(min_value=1e290, max_value=MAX),
        st.sampled_from([MAX, MAX - ULP_MAX, 1.5 * ULP_MAX, 1e300, 1e308]),
    ),
)
small_offset = st.one_of(
    st.just(0.0),
    tiny,
    st.floats(min_value=-1e-6, max_value=1e-6, allow_nan=False),
    st.floats(min_value=-0.5, max_value=0.5, allow_nan=False),
)
reals = st.one_of(any_finite, moderate, tiny, huge, small_offset)


def near(centers: st.SearchStrategy[float]) -> st.SearchStrategy[float]:
    """Floats a few ulps or a small offset away from the given centres."""
    return st.builds(
        lambda c, off, n: _nudge(c + off, n), centers, small_offset, st.integers(-4, 4)
    )


half_pi_multiples = st.integers(-16, 16).map(lambda k: k * (math.pi / 2))
two_pi_multiples = st.one_of(st.integers(-1000, 1000), st.integers(-(10**11), 10**11)).map(
    lambda k: k * (2 * math.pi)
)
angles = st.one_of(
    near(st.sampled_from([0.0, math.pi, -math.pi, math.pi / 2, -math.pi / 2])),
    near(half_pi_multiples),
    near(two_pi_multiples),
    st.floats(min_value=-10.0, max_value=10.0, allow_nan=False),
    st.floats(min_value=-1e12, max_value=1e12, allow_nan=False),
    st.builds(lambda s, m: s * m, signs, st.floats(min_value=1e12, max_value=1e14)),
    tiny,
    huge,
)


def intervals(values: st.SearchStrategy[float]) -> st.SearchStrategy[tuple[float, float]]:
    """Point intervals, intervals a few ulps wide, and arbitrary pairs of values."""
    point = values.map(lambda v: (v, v))
    ulps = st.builds(lambda v, n: (v, _nudge(v, n)), values, st.integers(1, 8))
    width = st.builds(
        lambda v, w: (v, v + w) if math.isfinite(v + w) else (v, v),
        values,
        st.one_of(
            st.floats(min_value=0.0, max_value=10.0), st.sampled_from([math.pi, 2 * math.pi])
        ),
    )
    pair = st.tuples(values, values).map(lambda p: (min(p), max(p)))
    return st.one_of(point, ulps, width, pair)


fractions = st.lists(st.floats(min_value=0.0, max_value=1.0), min_size=1, max_size=3)


def samples(bounds: tuple[float, float], ts: list[float]) -> list[float]:
    """The endpoints and a few floats in between (rounded to nearest, so still inside)."""
    lo, hi = bounds
    with mpmath.workprec(PREC):
        inner = [float(mpf(lo) + mpmath.mpf(t) * (mpf(hi) - mpf(lo))) for t in ts]
    return [lo, hi, *(min(max(p, lo), hi) for p in inner)]


# ---------------------------------------------------------------- constants and primitives


def test_pi_constants_bracket_pi():
    with mpmath.workprec(PREC):
        pi = mpmath.pi
        assert mpf(rnd.PI_LO) < pi < mpf(rnd.PI_HI)
        assert mpf(rnd.HALF_PI_LO) < pi / 2 < mpf(rnd.HALF_PI_HI)
        assert mpf(rnd.TWO_PI_LO) < 2 * pi < mpf(rnd.TWO_PI_HI)
    # and they are the tightest such doubles
    assert math.nextafter(rnd.PI_LO, math.inf) == rnd.PI_HI
    assert math.nextafter(rnd.HALF_PI_LO, math.inf) == rnd.HALF_PI_HI
    assert math.nextafter(rnd.TWO_PI_LO, math.inf) == rnd.TWO_PI_HI
    assert rnd.MAX == MAX and rnd.INF == math.inf


def test_fpu_rounds_to_nearest():
    """The directed sums (TwoSum) are only error-free in the default rounding mode.

    codac's gaol switches the FPU to upward rounding on import and leaves it there;
    tests/conftest.py and cuikslam's public entry points restore round-to-nearest. In
    upward mode this sum came out as 3.8685626227668134e25, above the exact one.
    """
    assert rounds_to_nearest()
    assert rnd.add_down(-9.285202997558387e-07, 3.8685626227668134e25) < 3.8685626227668134e25


PRIMITIVES = {
    "add": (rnd.add_down, rnd.add_up, lambda a, b: a + b),
    "sub": (rnd.sub_down, rnd.sub_up, lambda a, b: a - b),
    "mul": (rnd.mul_down, rnd.mul_up, lambda a, b: a * b),
    "div": (rnd.div_down, rnd.div_up, lambda a, b: a / b),
}


@settings(max_examples=2 * N, deadline=None)
@given(a=reals, b=reals, name=st.sampled_from(sorted(PRIMITIVES)))
@example(a=-1.5 * ULP_MAX, b=MAX, name="add")  # TwoSum's intermediate overflows
@example(a=MAX, b=-1.5 * ULP_MAX, name="add")
@example(a=1.5 * ULP_MAX, b=-MAX, name="add")
@example(a=MAX, b=1.5 * ULP_MAX, name="sub")
@example(a=MAX, b=MAX, name="add")
@example(a=TINY, b=0.5, name="mul")
@example(a=TINY, b=3.0, name="div")
def test_directed_primitives_bracket_exact(a, b, name):
    down, up, f = PRIMITIVES[name]
    assume(not (name == "div" and b == 0.0))
    with mpmath.workprec(PREC + 2200):  # exact sums of doubles need ~2100 bits
        exact = f(mpf(a), mpf(b))
        lo, hi = down(a, b), up(a, b)
        assert mpf(lo) <= exact <= mpf(hi), (name, a, b, lo, hi)


@settings(max_examples=N, deadline=None)
@given(a=st.one_of(any_finite, tiny, huge).map(abs))
def test_sqrt_primitives_bracket_exact(a):
    with mpmath.workprec(PREC):
        exact = mpmath.sqrt(mpf(a))
        assert mpf(rnd.sqrt_down(a)) <= exact <= mpf(rnd.sqrt_up(a))


# ---------------------------------------------------------------- arithmetic


BINARY = {
    "add": (ia.add, lambda a, b: a + b),
    "sub": (ia.sub, lambda a, b: a - b),
    "mul": (ia.mul, lambda a, b: a * b),
    "div": (ia.div, lambda a, b: a / b),
}


@settings(max_examples=3 * N, deadline=None)
@given(
    a=intervals(reals),
    b=intervals(reals),
    ta=fractions,
    tb=fractions,
    name=st.sampled_from(sorted(BINARY)),
)
@example(a=(15.0, 15.0), b=(0.0, 0.0), ta=[0.5], tb=[0.5], name="add")
@example(a=(-1.5 * ULP_MAX, 1.0), b=(MAX, MAX), ta=[0.0], tb=[0.0], name="add")
@example(a=(-3.0, 2.0), b=(0.0, 1e-300), ta=[0.5], tb=[1.0], name="div")
@example(a=(TINY, 1e-300), b=(-1e300, MAX), ta=[0.0], tb=[0.0], name="mul")
def test_binary_ops_contain_exact(a, b, ta, tb, name):
    op, f = BINARY[name]
    out = op(iv(*a), iv(*b))
    for x in samples(a, ta):
        for y in samples(b, tb):
            if name == "div" and y == 0.0:
                continue
            with mpmath.workprec(PREC + 2200):
                exact = f(mpf(x), mpf(y))
            assert inside(out, exact), (name, a, b, x, y, out)


def unbounded_intervals(values: st.SearchStrategy[float]):
    """Intervals with at least one infinite endpoint."""
    return st.one_of(
        values.map(lambda v: (-math.inf, v)),
        values.map(lambda v: (v, math.inf)),
        st.just((-math.inf, math.inf)),
    )


def finite_samples(bounds: tuple[float, float], ts: list[float]) -> list[float]:
    """Finite points of a possibly unbounded interval, its finite endpoints included."""
    lo, hi = bounds
    flo, fhi = max(lo, -MAX), min(hi, MAX)
    extra = [v for v in (-1e300, -1.0, -TINY, 0.0, TINY, 1.0, 1e300) if flo <= v <= fhi]
    return samples((flo, fhi), ts) + extra


@settings(max_examples=2 * N, deadline=None)
@given(
    a=st.one_of(unbounded_intervals(reals), intervals(reals)),
    b=unbounded_intervals(reals),
    ta=fractions,
    tb=fractions,
    name=st.sampled_from(sorted(BINARY)),
    swap=st.booleans(),
)
@example(a=(1e-300, math.inf), b=(-math.inf, -1e-8), ta=[0.0], tb=[1.0], name="div", swap=False)
@example(a=(-math.inf, -1.0), b=(-math.inf, -1.0), ta=[0.5], tb=[0.5], name="div", swap=False)
@example(a=(1.0, math.inf), b=(1.0, math.inf), ta=[0.5], tb=[0.5], name="div", swap=False)
def test_unbounded_binary_ops_contain_exact(a, b, ta, tb, name, swap):
    """inf / inf or 0 * inf corners must not turn into NaN and lose a bound."""
    if swap:
        a, b = b, a
    op, f = BINARY[name]
    out = op(iv(*a), iv(*b))
    assert not np.isnan(out).any(), (name, a, b, out)
    for x in finite_samples(a, ta):
        for y in finite_samples(b, tb):
            if name == "div" and y == 0.0:
                continue
            with mpmath.workprec(PREC + 2200):
                exact = f(mpf(x), mpf(y))
            assert inside(out, exact), (name, a, b, x, y, out)


@settings(max_examples=N, deadline=None)
@given(
    a=unbounded_intervals(reals), ts=fractions, name=st.sampled_from(["sqr", "sqrt", "sin", "cos"])
)
def test_unbounded_unary_ops_contain_exact(a, ts, name):
    out = getattr(ia, name)(iv(*a))
    assert not np.isnan(out).any(), (name, a, out)
    for x in finite_samples(a, ts):
        if name == "sqrt" and x < 0.0:
            continue
        with mpmath.workprec(prec_for(x)):
            exact = getattr(mpmath, name)(mpf(x)) if name != "sqr" else mpf(x) ** 2
        assert inside(out, exact), (name, a, x, out)


@settings(max_examples=N, deadline=None)
@given(a=intervals(reals), ts=fractions)
def test_sqr_contains_exact(a, ts):
    out = ia.sqr(iv(*a))
    assert out[0] >= 0.0
    for x in samples(a, ts):
        assert inside(out, mpf(x) ** 2), (a, x, out)


@settings(max_examples=N, deadline=None)
@given(a=intervals(reals), ts=fractions)
def test_sqrt_contains_exact(a, ts):
    out = ia.sqrt(iv(*a))
    if a[1] < 0.0:
        assert ia.is_empty(out)
    else:
        for x in samples(a, ts):
            if x >= 0.0:
                with mpmath.workprec(PREC):
                    assert inside(out, mpmath.sqrt(mpf(x))), (a, x, out)


@settings(max_examples=N, deadline=None)
@given(
    a=st.one_of(st.integers(-(2**40), 2**40).map(float), moderate, tiny),
    b=st.one_of(st.integers(-(2**40), 2**40).map(float), moderate, tiny),
)
@example(a=15.0, b=0.0)
@example(a=0.1, b=0.2)
@example(a=TINY, b=-TINY)
def test_exact_sums_stay_exact(a, b):
    """Width-0 inputs whose sum or difference is a double give a width-0 result."""
    for op, f in ((ia.add, lambda u, v: u + v), (ia.sub, lambda u, v: u - v)):
        out = op(iv(a, a), iv(b, b))
        with mpmath.workprec(PREC + 2200):
            exact = f(mpf(a), mpf(b))
        if exact == mpf(f(a, b)):
            assert out[0] == out[1] == f(a, b), (a, b, out)
        else:
            assert out[0] < out[1]
            assert inside(out, exact)


def test_documented_exact_examples():
    assert ia.add(iv(15.0, 15.0), iv(0.0, 0.0)).tolist() == [15.0, 15.0]
    assert ia.sub(iv(15.0, 15.0), iv(0.0, 0.0)).tolist() == [15.0, 15.0]
    assert ia.add(iv(1.0, 2.0), iv(-1.0, 3.0)).tolist() == [0.0, 5.0]
    assert ia.add(iv(0.5, 0.25 + 0.5), iv(0.25, 0.25)).tolist() == [0.75, 1.0]


# ---------------------------------------------------------------- angles


@settings(max_examples=2 * N, deadline=None)
@given(a=intervals(angles), ts=fractions, name=st.sampled_from(["sin", "cos"]))
@example(a=(math.pi, math.pi), ts=[0.5], name="sin")
@example(a=(math.pi / 2, math.pi / 2), ts=[0.5], name="cos")
@example(a=(1e12, 1e12), ts=[0.5], name="cos")
@example(a=(1e22, 1e22), ts=[0.5], name="sin")
@example(a=(TINY, TINY), ts=[0.5], name="sin")
@example(a=(-1e-300, 1e-300), ts=[0.5], name="cos")
def test_sin_cos_contain_exact(a, ts, name):
    op = ia.sin if name == "sin" else ia.cos
    out = op(iv(*a))
    assert -1.0 <= out[0] <= out[1] <= 1.0
    for x in samples(a, ts):
        with mpmath.workprec(prec_for(x)):
            exact = mpmath.sin(mpf(x)) if name == "sin" else mpmath.cos(mpf(x))
        assert inside(out, exact), (name, a, x, out)


@settings(max_examples=2 * N, deadline=None)
@given(y=intervals(reals), x=intervals(reals), ty=fractions, tx=fractions)
@example(y=(0.0, 0.0), x=(-1.0, -1.0), ty=[0.5], tx=[0.5])
@example(y=(-0.0, 1.0), x=(-2.0, -1.0), ty=[0.5], tx=[0.5])
@example(y=(TINY, TINY), x=(-1.0, -1.0), ty=[0.5], tx=[0.5])
@example(y=(1.0, 1.0), x=(TINY, TINY), ty=[0.5], tx=[0.5])
@example(y=(1e300, 1e300), x=(1e-300, 1e-300), ty=[0.5], tx=[0.5])
@example(y=(-1.0, 1.0), x=(-2.0, -1.0), ty=[0.5], tx=[0.5])
def test_atan2_contains_exact(y, x, ty, tx):
    out = ia.atan2(iv(*y), iv(*x))
    assert -rnd.PI_HI <= out[0] <= out[1] <= rnd.PI_HI
    for yv in samples(y, ty):
        for xv in samples(x, tx):
            if xv == 0.0 and yv == 0.0:
                continue
            with mpmath.workprec(PREC):
                exact = mpmath.atan2(mpf(yv), mpf(xv))
            assert inside(out, exact), (y, x, yv, xv, out)


@settings(max_examples=2 * N, deadline=None)
@given(
    x=intervals(angles),
    a=intervals(angles),
    ta=fractions,
    pick=st.lists(st.floats(min_value=0.0, max_value=1.0), min_size=1, max_size=3),
)
@example(x=(0.0, 6.2), a=(1e20, 1e20), ta=[0.5], pick=[0.5])  # A beyond the phase limit
@example(x=(0.0, 6.2), a=(-3e17, -3e17), ta=[0.5], pick=[0.5])
@example(x=(5.9, 6.6), a=(-0.1, 0.1), ta=[0.5], pick=[0.5])
@example(x=(-1e12, -1e12 + 3.0), a=(3.0, 3.2), ta=[0.5], pick=[0.5])
def test_periodic_intersect_keeps_congruent_points(x, a, ta, pick):
    """Every real of X congruent (mod 2π) to a point of A stays; an empty answer is a proof."""
    out = ia.periodic_intersect(iv(*x), iv(*a))
    xlo, xhi = x
    if not ia.is_empty(out):
        assert xlo <= out[0] <= out[1] <= xhi
    with mpmath.workprec(prec_for(xlo, xhi, *a) + 64):
        two_pi = 2 * mpmath.pi
        for av in samples(a, ta):
            k_lo = int(mpmath.ceil((mpf(xlo) - mpf(av)) / two_pi))
            k_hi = int(mpmath.floor((mpf(xhi) - mpf(av)) / two_pi))
            if k_lo > k_hi:
                continue
            ks = {k_lo, k_hi, *(min(k_hi, k_lo + int(p * (k_hi - k_lo))) for p in pick)}
            for k in ks:
                point = mpf(av) + k * two_pi
                assert inside(out, point), (x, a, av, k, out)
        # emptiness must be a proof: no copy of A meets X
        if ia.is_empty(out):
            k = mpmath.ceil((mpf(xlo) - mpf(a[1])) / two_pi)
            assert mpf(a[0]) + k * two_pi > mpf(xhi), (x, a)


# ---------------------------------------------------------------- no fastmath


def _package_modules():
    modules = []
    for info in pkgutil.walk_packages(cuikslam.__path__, prefix="cuikslam."):
        try:
            modules.append(importlib.import_module(info.name))
        except Exception:  # a module others are editing right now; the grep still covers it
            continue
    return modules


def test_jit_options_forbid_fastmath():
    assert _jit.JIT_OPTIONS["fastmath"] is False
    source = inspect.getsource(_jit.gufunc)
    assert "fastmath=False" in source and "fastmath=True" not in source


def test_no_kernel_compiled_elsewhere_or_with_fastmath():
    root = Path(cuikslam.__file__).parent
    pattern = re.compile(
        r"fastmath\s*=\s*True|numba\.njit\s*\(|@njit|@numba\.jit|numba\.jit\s*\(|guvectorize\s*\("
        r"|numba\.vectorize|@vectorize|from numba import"
    )
    offenders = []
    for path in sorted(root.rglob("*.py")):
        if path.name == "_jit.py" and path.parent == root:
            continue
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if pattern.search(line):
                offenders.append(f"{path.relative_to(root)}:{n}: {line.strip()}")
    assert offenders == [], "compiled kernels must go through cuikslam._jit:\n" + "\n".join(
        offenders
    )


def test_every_compiled_kernel_has_fastmath_off():
    seen = 0
    for module in _package_modules():
        for value in vars(module).values():
            if isinstance(value, CPUDispatcher):
                assert not value.targetoptions.get("fastmath"), (module.__name__, value)
                seen += 1
            elif isinstance(value, GUFunc):
                assert not value.gufunc_builder.targetoptions.get("fastmath"), (
                    module.__name__,
                    value,
                )
                seen += 1
    assert seen > 30  # the interval kernel alone has dozens
