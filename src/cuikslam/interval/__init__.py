"""The interval kernel: outward-rounded interval arithmetic and angles, over NumPy arrays.

One kernel serves the whole library: the compiled scalar functions in ``_arith`` and
``_periodic`` are used by the narrowing operators, and the same functions, wrapped as
generalized ufuncs, form the public array API of :mod:`cuikslam.interval.ops`, reachable
from here. What the rest of the library asks of an angle in plain Python (enclosures of
π, exact containment modulo 2π, a sensor's out-of-view arc) is :mod:`.angles`.

Nothing compiled is loaded by importing this package: the array operations are loaded
on first use, so :mod:`.angles` stays light.
"""

from __future__ import annotations

import importlib
from typing import Any


def __getattr__(name: str) -> Any:
    """An array operation of :mod:`cuikslam.interval.ops`, compiled on first use."""
    ops = importlib.import_module("cuikslam.interval.ops")
    if name == "__all__" or name in ops.__all__:
        return getattr(ops, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__() -> list[str]:
    ops = importlib.import_module("cuikslam.interval.ops")
    return sorted({*globals(), *ops.__all__})
