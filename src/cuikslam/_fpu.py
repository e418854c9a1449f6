"""Guard of the floating-point rounding mode that the interval kernel relies on.

The kernel computes each operation rounded to nearest and then moves it outward; its
error-free sums are exact only in that mode. Some libraries switch the whole process to
another mode and leave it there: codac (IBEX with gaol) sets rounding upward at its first
use. Every public entry point of cuikslam calls :func:`ensure_round_to_nearest`, which
restores round-to-nearest (C ``fesetround``) or refuses to run.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import sys
from collections.abc import Callable
from typing import Any, TypeVar

__all__ = ["ensure_round_to_nearest", "guarded", "rounds_to_nearest"]

# Exact operands written in hex: no arithmetic at import time, whose result would depend
# on the very rounding mode being checked (and no constant folding by the compiler).
_ONE = float.fromhex("0x1p0")
_TINY = float.fromhex("0x1p-57")
_THREE_QUARTER_ULP = float.fromhex("0x1.8p-53")
_NEXT_AFTER_ONE = float.fromhex("0x1.0000000000001p0")
_FE_TONEAREST = 0


def rounds_to_nearest() -> bool:
    """True when this thread's floating-point operations round to nearest."""
    up_or_nearest_down = _ONE + _TINY == _ONE  # False when rounding upward
    not_truncating = _ONE + _THREE_QUARTER_ULP == _NEXT_AFTER_ONE  # False toward zero / down
    not_downward = -_ONE - _TINY == -_ONE  # False when rounding downward
    return up_or_nearest_down and not_truncating and not_downward


@functools.cache
def _libm() -> ctypes.CDLL | None:
    name = ctypes.util.find_library("m") or (
        "libm.so.6" if sys.platform.startswith("linux") else None
    )
    if name is None:
        return None
    try:
        return ctypes.CDLL(name)
    except OSError:
        return None


def ensure_round_to_nearest() -> None:
    """Restore round-to-nearest if another library changed it; raise if that is impossible."""
    if rounds_to_nearest():
        return
    libm = _libm()
    if libm is not None:
        libm.fesetround(_FE_TONEAREST)
    if not rounds_to_nearest():
        raise RuntimeError(
            "the floating-point rounding mode is not round-to-nearest (another library, "
            "e.g. codac/IBEX, changed it) and cuikslam could not restore it; its outward "
            "rounding would not be guaranteed"
        )


F = TypeVar("F", bound=Callable[..., Any])


def guarded(func: F) -> F:
    """Wrap ``func`` so it runs only in round-to-nearest mode."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        ensure_round_to_nearest()
        return func(*args, **kwargs)

    return wrapper  # type: ignore[return-value]
