"""The interval kernel: outward-rounded interval arithmetic and angles, over NumPy arrays.

One kernel serves the whole library: the compiled scalar functions in ``_arith`` and
``_periodic`` are used by the narrowing operators, and the same functions, wrapped as
generalized ufuncs, form the public array API below.
"""

from cuikslam.interval.ops import *  # noqa: F403
from cuikslam.interval.ops import __all__  # noqa: F401
