"""Vectorized interval operations on NumPy arrays.

An interval array is a float64 array whose last axis holds ``(lo, hi)``; leading axes
broadcast like any NumPy operation, so ``add(a, b)`` adds many intervals at once in
compiled code. An interval is empty when ``lo > hi``. Every result is rounded outward.

Examples
--------
>>> import numpy as np
>>> from cuikslam import interval as ia
>>> x = np.array([[1.0, 2.0], [-1.0, 3.0]])
>>> ia.sqr(x).tolist()  # products move outward by a few ulps at most
[[0.9999999999999998, 4.000000000000001], [0.0, 9.000000000000002]]
>>> ia.add(x, x).tolist()  # exact sums stay exact
[[2.0, 4.0], [-2.0, 6.0]]
>>> bool(ia.is_empty(ia.intersect(np.array([0.0, 1.0]), np.array([2.0, 3.0]))))
True
>>> ia.angle_of(np.array([-0.1, 0.1]), np.array([-2.0, -1.0]), np.array([3.0, 3.3]))[2].round(4)
array([3.0419, 3.2413])
"""

from __future__ import annotations

import threading
from collections.abc import Callable

import numpy as np

from cuikslam._fpu import guarded
from cuikslam._jit import gufunc
from cuikslam.interval import _arith, _periodic

__all__ = [
    "EMPTY",
    "add",
    "angle_of",
    "atan2",
    "bwd_add",
    "bwd_cos",
    "bwd_mul",
    "bwd_sin",
    "bwd_sqr",
    "bwd_sqrt",
    "bwd_sub",
    "compile_all",
    "contains",
    "cos",
    "div",
    "hull",
    "intersect",
    "interval",
    "is_empty",
    "mul",
    "neg",
    "periodic_intersect",
    "sin",
    "sqr",
    "sqrt",
    "sub",
    "width",
]

EMPTY = np.array([np.inf, -np.inf])
"""The canonical empty interval."""

_F = "float64[:]"
_UNARY = [f"void({_F}, {_F})"]
_BINARY = [f"void({_F}, {_F}, {_F})"]
_BWD_BINARY = [f"void({_F}, {_F}, {_F}, {_F}, {_F})"]
_BWD_UNARY = [f"void({_F}, {_F}, {_F})"]


_KERNELS: dict[str, tuple[Callable, list[str], str]] = {}
"""Each array operation's Python kernel, signatures and layout, compiled on first use."""
_COMPILING = threading.Lock()


def _kernel(signatures: list[str], layout: str) -> Callable[[Callable], Callable]:
    """Register a generalized ufunc, compiled (or loaded from numba's cache) on first use.

    Loading all of them at import took half a second, paid by every command, though a
    solve at level ``hull`` uses none of them and level ``lp`` a third.
    """

    def register(func: Callable) -> Callable:
        _KERNELS[func.__name__] = (func, signatures, layout)
        return func

    return register


def interval(lo: np.typing.ArrayLike, hi: np.typing.ArrayLike | None = None) -> np.ndarray:
    """Stack lower and upper bounds into an interval array (``hi`` defaults to ``lo``: points)."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = lo if hi is None else np.asarray(hi, dtype=np.float64)
    lo, hi = np.broadcast_arrays(lo, hi)
    return np.stack([lo, hi], axis=-1)


def is_empty(x: np.ndarray) -> np.ndarray:
    """True where the interval is empty."""
    x = np.asarray(x)
    return x[..., 0] > x[..., 1]


def width(x: np.ndarray) -> np.ndarray:
    """Width ``hi - lo`` (0 for empty intervals)."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(is_empty(x), 0.0, x[..., 1] - x[..., 0])


def contains(x: np.ndarray, value: np.typing.ArrayLike) -> np.ndarray:
    """True where ``value`` lies in the interval."""
    x = np.asarray(x, dtype=np.float64)
    value = np.asarray(value, dtype=np.float64)
    return (x[..., 0] <= value) & (value <= x[..., 1])


@_kernel(_BINARY, "(n),(n)->(n)")
def intersect(a, b, out):
    out[0], out[1] = _arith.meet(a[0], a[1], b[0], b[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def hull(a, b, out):
    out[0], out[1] = _arith.join(a[0], a[1], b[0], b[1])


@_kernel(_UNARY, "(n)->(n)")
def neg(a, out):
    out[0], out[1] = _arith.neg(a[0], a[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def add(a, b, out):
    out[0], out[1] = _arith.add(a[0], a[1], b[0], b[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def sub(a, b, out):
    out[0], out[1] = _arith.sub(a[0], a[1], b[0], b[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def mul(a, b, out):
    out[0], out[1] = _arith.mul(a[0], a[1], b[0], b[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def div(a, b, out):
    out[0], out[1] = _arith.div(a[0], a[1], b[0], b[1])


@_kernel(_UNARY, "(n)->(n)")
def sqr(a, out):
    out[0], out[1] = _arith.sqr(a[0], a[1])


@_kernel(_UNARY, "(n)->(n)")
def sqrt(a, out):
    out[0], out[1] = _arith.sqrt(a[0], a[1])


@_kernel(_UNARY, "(n)->(n)")
def cos(a, out):
    out[0], out[1] = _periodic.cos(a[0], a[1])


@_kernel(_UNARY, "(n)->(n)")
def sin(a, out):
    out[0], out[1] = _periodic.sin(a[0], a[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def atan2(y, x, out):
    out[0], out[1] = _periodic.atan2(y[0], y[1], x[0], x[1])


@_kernel(_BINARY, "(n),(n)->(n)")
def periodic_intersect(x, a, out):
    out[0], out[1] = _periodic.periodic_meet(x[0], x[1], a[0], a[1])


@_kernel(_BWD_BINARY, "(n),(n),(n)->(n),(n)")
def bwd_add(z, x, y, x_out, y_out):
    x_out[0], x_out[1], y_out[0], y_out[1] = _arith.bwd_add(z[0], z[1], x[0], x[1], y[0], y[1])


@_kernel(_BWD_BINARY, "(n),(n),(n)->(n),(n)")
def bwd_sub(z, x, y, x_out, y_out):
    x_out[0], x_out[1], y_out[0], y_out[1] = _arith.bwd_sub(z[0], z[1], x[0], x[1], y[0], y[1])


@_kernel(_BWD_BINARY, "(n),(n),(n)->(n),(n)")
def bwd_mul(z, x, y, x_out, y_out):
    x_out[0], x_out[1], y_out[0], y_out[1] = _arith.bwd_mul(z[0], z[1], x[0], x[1], y[0], y[1])


@_kernel(_BWD_UNARY, "(n),(n)->(n)")
def bwd_sqr(z, x, x_out):
    x_out[0], x_out[1] = _arith.bwd_sqr(z[0], z[1], x[0], x[1])


@_kernel(_BWD_UNARY, "(n),(n)->(n)")
def bwd_sqrt(z, x, x_out):
    x_out[0], x_out[1] = _arith.bwd_sqrt(z[0], z[1], x[0], x[1])


@_kernel(_BWD_UNARY, "(n),(n)->(n)")
def bwd_cos(z, x, x_out):
    x_out[0], x_out[1] = _periodic.bwd_cos(z[0], z[1], x[0], x[1])


@_kernel(_BWD_UNARY, "(n),(n)->(n)")
def bwd_sin(z, x, x_out):
    x_out[0], x_out[1] = _periodic.bwd_sin(z[0], z[1], x[0], x[1])


@_kernel([f"void({_F}, {_F}, {_F}, {_F}, {_F}, {_F})"], "(n),(n),(n)->(n),(n),(n)")
def angle_of(y, x, theta, y_out, x_out, theta_out):
    (x_out[0], x_out[1], y_out[0], y_out[1], theta_out[0], theta_out[1]) = _periodic.arg_contract(
        x[0], x[1], y[0], y[1], theta[0], theta[1]
    )


_DOCS: dict[str, str] = {
    "intersect": "Intersection of interval arrays.",
    "hull": "Interval hull (smallest interval containing both).",
    "neg": "Negation.",
    "add": "Sum, rounded outward.",
    "sub": "Difference, rounded outward.",
    "mul": "Product, rounded outward (0 * inf = 0).",
    "div": "Hull of a / b over b != 0 (relational division; unbounded when 0 is inside b).",
    "sqr": "Square, rounded outward.",
    "sqrt": "Square root of the non-negative part, rounded outward.",
    "cos": "Cosine of an unwrapped angle interval, rounded outward.",
    "sin": "Sine of an unwrapped angle interval, rounded outward.",
    "atan2": "Principal angle atan2(y, x) in [-pi, pi] (with its cut); prefer angle_of.",
    "periodic_intersect": "Hull of x ∩ (a + 2 pi Z): angles of x congruent to an angle of a.",
    "bwd_add": "Narrow (x, y) under z = x + y; returns (x', y').",
    "bwd_sub": "Narrow (x, y) under z = x - y; returns (x', y').",
    "bwd_mul": "Narrow (x, y) under z = x * y; returns (x', y').",
    "bwd_sqr": "Narrow x under z = x**2; returns x'.",
    "bwd_sqrt": "Narrow x under z = sqrt(x); returns x'.",
    "bwd_cos": "Narrow the angle x under z = cos(x); returns x'.",
    "bwd_sin": "Narrow the angle x under z = sin(x); returns x'.",
    "angle_of": (
        "Narrow (y, x, theta) under theta ≡ angle of (x, y) mod 2 pi, theta unwrapped: atan2"
        " without its cut. Returns (y', x', theta')."
    ),
}
for _name in _KERNELS:  # module attributes only through __getattr__: compiled on first use
    del globals()[_name]


def compile_all() -> None:
    """Compile (or load from numba's cache) every array operation now.

    Two processes that compile the same operation at once can leave numba's cache of a
    generalized ufunc inconsistent and crash the one that loads it (numba issue 10128);
    ``cuikslam warm-up`` and the test suite's parallel run compile them all first, in one
    process.
    """
    for name in _KERNELS:
        __getattr__(name)


def __getattr__(name: str) -> Callable:
    """The array operation ``name``, compiled on first use (then a plain attribute)."""
    if name not in _KERNELS:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    with _COMPILING:
        if name not in globals():
            func, signatures, layout = _KERNELS[name]
            compiled = gufunc(signatures, layout)(func)
            compiled.__doc__ = _DOCS[name]
            globals()[name] = guarded(compiled)
    return globals()[name]


def __dir__() -> list[str]:
    return sorted({*globals(), *_KERNELS})
