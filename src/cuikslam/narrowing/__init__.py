"""Narrowing operators of the factors and their chaotic iteration to a fixpoint.

Every narrowing function follows one protocol (see :mod:`.propagation`): it narrows the
bounds it is given in place and returns a :class:`Propagation` with a :class:`Status`.
"""

from cuikslam.narrowing.propagation import (
    DEFAULT_RTOL,
    Arrays,
    Propagation,
    Status,
    narrow,
    propagate,
)

__all__ = ["DEFAULT_RTOL", "Arrays", "Propagation", "Status", "narrow", "propagate"]
