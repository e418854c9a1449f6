"""Narrowing operators of the factors and their chaotic iteration to a fixpoint."""

from cuikslam.narrowing.propagation import DEFAULT_RTOL, Propagation, Status, propagate

__all__ = ["DEFAULT_RTOL", "Propagation", "Status", "propagate"]
