"""The one place where numba options are set for every compiled kernel.

``fastmath`` is forbidden: it lets LLVM reassociate and contract floating-point
operations, which silently breaks outward rounding. ``error_model="numpy"`` makes a
division by zero return inf/nan instead of raising, as the interval code expects.
``cache=True`` stores compiled code on disk so a second run pays no compile time.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba

__all__ = ["JIT_OPTIONS", "gufunc", "jit"]

JIT_OPTIONS: dict[str, Any] = {
    "cache": True,
    "nogil": True,
    "fastmath": False,
    "error_model": "numpy",
}


def jit(func: Callable) -> Callable:
    """Compile ``func`` in nopython mode with the project's options."""
    return numba.njit(**JIT_OPTIONS)(func)


def gufunc(signatures: list[str], layout: str) -> Callable[[Callable], Callable]:
    """Compile a NumPy generalized ufunc (broadcasting over leading axes) with our options."""
    return numba.guvectorize(signatures, layout, nopython=True, cache=True, fastmath=False)
