"""The ``lp`` sweeps on both cores: the chain's windows cut into a fixed number of parts,
each swept on its own copy of the bounds, the copies then intersected.

A long log's windows (:func:`.sweeps.chain_windows`) are cut into ``PARTS`` runs of
consecutive windows (logs of fewer than ``MIN_PART_WINDOWS`` windows per part are one
part, swept as before, on the bounds themselves). At every sweep each part starts from a
copy of the same bounds and visits its own windows, in the sweep's direction, with its own
propagation buffers, stale marks and LP counts; the windows' warm starts belong to the one
part that visits them. Each part's narrowing is sound on its own (it contains every
solution in the box it started from), so their intersection is sound too, and an empty
part, or an empty intersection, proves that the graph has no solution.

Which thread runs which part does not change anything a part computes, and the copies are
merged by ``max`` / ``min`` (exact, and the same in any order), LP counts added in part
order: the boxes are the same for any number of threads and any thread timing. The
threads only decide how many parts run at once. The heavy parts of a window (the compiled
LP sequence kernel, the safe bounds and propagation, HiGHS) release the GIL; building a
window's relaxation (NumPy on small arrays) holds it.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import Budget
from cuikslam.interval.angles import TWO_PI_LO
from cuikslam.narrowing.lp_bounds import LpStatistics

__all__ = ["MIN_PART_WINDOWS", "PARTS", "Part", "default_threads", "partition", "run_parts"]

PARTS = 2
"""Parts of a long log's chain (fixed: the boxes do not depend on the machine)."""
MIN_PART_WINDOWS = 40
"""Windows per part at least (200 poses); shorter logs are one part."""


def partition(n_windows: int) -> list[range]:
    """The parts of ``n_windows`` windows: ``PARTS`` runs of consecutive windows, as even
    as possible, or one run when a part would hold fewer than ``MIN_PART_WINDOWS``.

    >>> partition(10)
    [range(0, 10)]
    >>> partition(199)
    [range(0, 100), range(100, 199)]
    """
    parts = max(1, min(PARTS, n_windows // MIN_PART_WINDOWS))
    edges = [round(k * n_windows / parts) for k in range(parts + 1)]
    return [range(edges[k], edges[k + 1]) for k in range(parts)]


def default_threads() -> int:
    """Cores this process may use that other processes are not already using: the CPUs
    of its affinity less the 1-minute load average, rounded, at least 1.

    With a second job running on a 2-core machine this is 1, and the parts run one after
    the other (no slower than before: the same work, no thread switching).
    """
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cpus = os.cpu_count() or 1
    try:
        load = os.getloadavg()[0]
    except OSError:
        load = 0.0
    return max(1, min(cpus, int(cpus - load + 0.5)))


class Part:
    """A run of consecutive windows and what one worker keeps for it between sweeps.

    Parameters
    ----------
    windows : range
        The indices of its windows along the chain.
    n_variables : int
        Length of the bounds.
    propagator : callable
        ``propagator(lo, hi, touched, max_applications) -> (status, applications)``, with
        buffers of its own (a part's propagation must not share them with another's).
    """

    def __init__(self, windows: range, n_variables: int, propagator: Callable) -> None:
        self.windows = windows
        self.propagate = propagator
        self.stale_lo = np.zeros(n_variables, dtype=bool)
        self.stale_hi = np.zeros(n_variables, dtype=bool)
        self.lp = LpStatistics()
        self.applications = 0
        self.lo: np.ndarray | None = None
        self.hi: np.ndarray | None = None
        self.first = windows.start == 0
        """The part at the start of the chain (it reports the sweeps' progress)."""
        self.cut = False
        """Whether the deadline stopped its last sweep."""
        self.budget: Budget | None = None
        """The budget of its next sweep (a meter of its own when there are several parts,
        so that what it does does not depend on how the threads interleave)."""
        self.abandon = False
        """Set when another part failed: the part stops at its next window."""

    def order(self, forward: bool) -> Sequence[int]:
        """Its windows in the sweep's direction."""
        return self.windows if forward else self.windows[::-1]


def run_parts(
    parts: list[Part],
    lo: np.ndarray,
    hi: np.ndarray,
    sweep: Callable[[Part, np.ndarray, np.ndarray], bool],
    threads: int,
) -> tuple[bool, bool]:
    """One sweep of every part, each on a copy of ``lo`` / ``hi``, then their intersection
    written into ``lo`` / ``hi`` (in place).

    ``sweep(part, lo, hi)`` visits the part's windows, narrowing its copy in place, and
    returns False when it proved the graph inconsistent. The first part runs in this
    thread, the others on up to ``threads - 1`` more threads.

    A variable whose box was wider than 2π before the sweep and whose parts' boxes do not
    meet gets their hull instead: a heading narrowed from such a box keeps one 2π copy of
    its interval (:mod:`cuikslam.interval.angles`), and two parts may keep different
    copies of the same headings.

    Returns
    -------
    tuple of bool
        ``(consistent, empty)``: ``consistent`` is False when a part proved the graph
        inconsistent, ``empty`` is True when the intersection of the parts is empty (also
        a proof).
    """

    def one(part: Part) -> bool:
        ensure_round_to_nearest()  # the rounding mode is per thread
        part.lo, part.hi = lo.copy(), hi.copy()
        return sweep(part, part.lo, part.hi)

    if threads <= 1 or len(parts) == 1:
        results = [one(part) for part in parts]
    else:
        with ThreadPoolExecutor(max_workers=min(threads, len(parts)) - 1) as pool:
            futures = [pool.submit(one, part) for part in parts[1:]]
            try:
                first = one(parts[0])
            except BaseException:  # e.g. Ctrl-C: the other threads stop at their next window
                for part in parts:
                    part.abandon = True
                raise
            results = [first] + [future.result() for future in futures]
    if not all(results):
        return False, False
    with np.errstate(invalid="ignore", over="ignore"):  # inf - inf: NaN, counted wide
        wide = ~(hi - lo < TWO_PI_LO)  # boxes at least 2π wide before the sweep
    for part in parts:
        np.maximum(lo, part.lo, out=lo)
        np.minimum(hi, part.hi, out=hi)
    apart = (lo > hi) & wide
    if apart.any():
        # a heading narrowed from a box wider than 2π keeps one 2π copy of its interval,
        # and two parts may keep different copies: their hull holds both, soundly
        lo[apart] = np.min([part.lo[apart] for part in parts], axis=0)
        hi[apart] = np.max([part.hi[apart] for part in parts], axis=0)
    return True, bool(np.any(lo > hi))
