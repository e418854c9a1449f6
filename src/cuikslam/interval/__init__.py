"""The interval kernel: outward-rounded interval arithmetic and angles, over NumPy arrays.

One kernel serves the whole library: the compiled scalar functions in ``_arith`` and
``_periodic`` are used by the narrowing operators, and the same functions, wrapped as
generalized ufuncs, form the public array API below.
"""

from cuikslam.interval import ops as _ops
from cuikslam.interval.ops import __all__, contains, interval, is_empty, width  # noqa: F401


def __getattr__(name: str):
    """An array operation of :mod:`cuikslam.interval.ops`, compiled on first use."""
    if name in __all__:
        return getattr(_ops, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
