"""Time budgets: every stage of a solve that could run long stops at a deadline.

A *deadline* is a point on the :func:`time.perf_counter` clock (a float), or None for no
limit. Stages take one as a keyword argument (``deadline=``), check it between units of
work (an LP, a window of LPs, a local optimisation) and, when it has passed, stop with
whatever *sound* result they have: boxes narrowed so far (every narrowing step keeps every
solution, so stopping early only leaves boxes wider), or a hypothesis left ``not refuted``
(never claimed proven). They say so in their report, so the result can be honest about
what was reached.

:func:`cuikslam.solver.solve` turns its ``time_budget`` (seconds for the whole solve) into
deadlines for its stages: the stronger consistency level may use the first
``STRENGTHEN_SHARE`` of the budget, the witness search what is left.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = [
    "COMMAND_TARGET",
    "DEFAULT_TIME_BUDGET",
    "MIN_COMMAND_BUDGET",
    "SECONDS_PER_POSE",
    "STRENGTHEN_SHARE",
    "OutOfTime",
    "blas_single_thread",
    "command_budget",
    "deadline_after",
    "expired",
    "portion",
    "remaining",
]

DEFAULT_TIME_BUDGET = 2.0
"""Seconds a solve may take by default (``cuikslam solve --time-budget``).

Chosen so that ``cuikslam solve`` on a short log finishes within a few seconds end to end,
start-up (Python, the solver's imports, its compiled kernels) included; the figures are
measured by ``benchmarks/bench_end_to_end.py`` and reported in the README."""
COMMAND_TARGET = 4.0
"""Seconds ``cuikslam solve`` aims at end to end with its default ``--time-budget auto``:
the solve gets what start-up (imports, loading the compiled kernels) left of it..."""
MIN_COMMAND_BUDGET = 1.0
"""...but at least this much..."""
SECONDS_PER_POSE = 0.15
"""...and at least this much per pose of the log. The default level's LP sweeps cost a
roughly constant time per pose (measured by ``benchmarks/bench_long_logs.py``, figures
in the README), so a long log gets time in proportion: its first sweep reaches the end of
the log, and the result says ``lp (budget)`` when the later sweeps were cut."""
STRENGTHEN_SHARE = 0.7
"""Fraction of the time left after hull narrowing that the stronger level may use; the
witness search gets the rest (and whatever the stronger level did not need)."""


class OutOfTime(Exception):
    """Raised inside a stage's inner loop when its deadline has passed (caught by the stage)."""


def command_budget(spent: float, n_poses: int) -> float:
    """Seconds a solve gets under ``cuikslam solve --time-budget auto``.

    Parameters
    ----------
    spent : float
        Seconds the command has already spent (start-up, reading the log).
    n_poses : int
        Poses in the log.

    Returns
    -------
    float
        What start-up left of ``COMMAND_TARGET``, at least ``MIN_COMMAND_BUDGET`` and at
        least ``SECONDS_PER_POSE`` per pose.
    """
    return max(MIN_COMMAND_BUDGET, COMMAND_TARGET - spent, SECONDS_PER_POSE * n_poses)


def deadline_after(seconds: float | None) -> float | None:
    """The deadline ``seconds`` from now, or None (no limit) for None or infinity.

    Parameters
    ----------
    seconds : float or None
        Time allowed; negative values are treated as zero.

    Returns
    -------
    float or None
        A value of :func:`time.perf_counter`, or None.
    """
    if seconds is None or math.isinf(seconds):
        return None
    return time.perf_counter() + max(0.0, float(seconds))


def remaining(deadline: float | None) -> float:
    """Seconds left before ``deadline`` (infinity without one, never negative)."""
    if deadline is None:
        return math.inf
    return max(0.0, deadline - time.perf_counter())


def expired(deadline: float | None) -> bool:
    """True when ``deadline`` is set and has passed."""
    return deadline is not None and time.perf_counter() >= deadline


def portion(deadline: float | None, fraction: float) -> float | None:
    """A deadline for a stage that may use ``fraction`` of the time left before ``deadline``.

    Parameters
    ----------
    deadline : float or None
        The overall deadline (None: no limit, and None is returned).
    fraction : float
        Between 0 and 1.

    Returns
    -------
    float or None
        ``now + fraction * remaining(deadline)``.
    """
    if deadline is None:
        return None
    now = time.perf_counter()
    return now + fraction * max(0.0, deadline - now)


@contextmanager
def blas_single_thread() -> Iterator[None]:
    """Run the block with one BLAS thread (OpenBLAS, MKL...), when threadpoolctl is present.

    The witness search factorises many tiny matrices (an SVD per least-squares step); a
    multi-threaded BLAS spends more on waking its threads than on the work: on a loaded
    machine, many times slower than one thread.

    threadpoolctl limits only the libraries loaded when the block starts, and scipy ships
    its own OpenBLAS (apart from numpy's): it is loaded first, or scipy's factorisations in
    the block would run on every core, many times slower on a loaded machine.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        yield
        return
    try:
        import scipy.linalg  # noqa: F401  (its BLAS must be loaded to be limited)
    except ImportError:  # pragma: no cover - scipy is a dependency
        pass
    with threadpool_limits(limits=1, user_api="blas"):
        yield
