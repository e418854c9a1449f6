"""The sweeps of the ``lp`` level: the polytope-hull operator (:func:`.polytope.tighten`)
over overlapping windows of consecutive poses, forward then backward along the chain,
each sweep followed by propagation, until a sweep stalls (see
:mod:`.consistency` for the levels built on them).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from cuikslam.budget import COSTS, Budget, expired, spend
from cuikslam.graph.encoding import KIND, OBSERVATION, ODOMETRY, RELATIVE, ROTATION, TA, TB, XA, XB
from cuikslam.narrowing._factors import fresh_memory
from cuikslam.narrowing._propagate import propagate_buffered
from cuikslam.narrowing.lp_bounds import LpStatistics
from cuikslam.narrowing.parts import Part, default_threads, partition, run_parts
from cuikslam.narrowing.polytope import WarmStarts, tighten
from cuikslam.narrowing.propagation import Arrays, Status

if TYPE_CHECKING:
    from cuikslam.narrowing.consistency import StrengthenReport

__all__ = ["Window", "chain_windows", "polytope_rounds"]

WINDOW_POSES = 10
"""Poses per window of the polytope-hull operator."""
WINDOW_OVERLAP = 5
"""Poses shared by consecutive windows."""
LOCAL_SPAN = 4
"""Before a window's LPs, its factors are propagated, with at most this many operator
applications per factor of the window (the LPs' relaxation is tighter on narrower boxes;
the cap keeps the cost of a window independent of the log's length)."""
MAX_LP_ROUNDS = 12
MIN_GAIN = 0.005
"""Stop after a sweep that shrinks the total width by less than this fraction."""
CENTRAL_ONLY = True
"""Each pose is bounded by one window per sweep (see ``_central``)."""
REUSE_FROM = 3
"""From this sweep on (counting from 0), no LP is solved: each bound is the safe bound of
the multipliers of its last LP over the window's new relaxation (see
``lp_bounds.certified_bounds(reuse=True)``). It follows the neighbours' narrowing while
the LP's optimal basis stays optimal (measured in ``docs/benchmarks.md``, "Long
logs")."""
REUSE_MIN_WINDOWS = 8
"""Logs with fewer windows solve every sweep's LPs: there the later sweeps gain from the
relaxation of narrower boxes, not only from the neighbours (on the seed's experiment, one
window, reusing multipliers made the worst box markedly wider; ``docs/benchmarks.md``,
"Long logs")."""
FULL_ROUND_EVERY = 3
"""Every this many sweeps, stale bounds are solved again all the same."""
UNSTALE_SHRINK = 0.02
"""A window's stale bounds are solved again once the widths of its variables have shrunk
by about this fraction since its last LPs (in the mean of their logarithms)."""
STALE_GAIN = 0.01
"""A bound whose LP moved it by less than this fraction of its width is left alone (see
``polytope_rounds``)."""


@dataclass
class Window:
    """A window of consecutive poses: its factors (indices and rows) and the variables it
    narrows (positions and headings of its poses, positions of the landmarks they see)."""

    indices: np.ndarray
    rows: np.ndarray
    targets: np.ndarray
    """Every variable of the window's poses and landmarks (sorted)."""
    headings: np.ndarray
    bounded: np.ndarray
    """The variables whose bounds this window's LPs compute, x coordinates first, then y,
    then headings, each in the order of the chain: consecutive LPs then have nearby
    optima, so each starts close to the last one's basis."""


def chain_windows(factors: np.ndarray) -> list[Window]:
    """Overlapping windows of consecutive poses, in the order of the chain.

    A window holds every odometry factor between two of its poses and every observation
    from one of them; built in time linear in the number of factors.
    """
    kept = np.flatnonzero(np.isin(factors[:, KIND], (ODOMETRY, OBSERVATION, RELATIVE, ROTATION)))
    rows = factors[kept]
    if len(rows) == 0:
        return []
    odo = np.isin(rows[:, KIND], (ODOMETRY, RELATIVE, ROTATION))  # pose to pose
    turns = np.isin(rows[:, KIND], (ODOMETRY, ROTATION))  # with a heading tb
    poses = np.unique(np.concatenate([rows[:, XA], rows[odo, XB]]))
    first = np.searchsorted(poses, rows[:, XA])
    last = np.where(odo, np.searchsorted(poses, np.where(odo, rows[:, XB], rows[:, XA])), first)
    first, last = np.minimum(first, last), np.maximum(first, last)
    if len(poses) <= WINDOW_POSES:
        starts = [0]
    else:
        starts = list(range(0, len(poses) - WINDOW_OVERLAP, WINDOW_POSES - WINDOW_OVERLAP))
    order = np.argsort(first, kind="stable")
    sorted_first = first[order]
    landmark_x = np.unique(rows[rows[:, KIND] == OBSERVATION, XB])
    windows = []
    for start in starts:
        end = start + WINDOW_POSES
        span = np.searchsorted(sorted_first, [start, end])
        candidates = order[span[0] : span[1]]
        inside = np.sort(candidates[last[candidates] < end])
        selected, selected_turns = rows[inside], turns[inside]
        b = selected[:, XB]
        targets = [selected[:, XA], selected[:, XA] + 1, selected[:, TA], b, b + 1]
        targets.append(selected[selected_turns, TB])
        headings = np.unique(np.concatenate([selected[:, TA], selected[selected_turns, TB]]))
        targets = np.unique(np.concatenate(targets))
        low, high = _central(start, end, len(poses))
        seen = selected[:, KIND] == OBSERVATION
        landmarks = np.concatenate([selected[seen, XB], selected[seen, XB] + 1])
        bounded = _bounded(targets, poses, low, high, landmarks, landmark_x)
        windows.append(Window(kept[inside], selected, targets, headings, bounded))
    return windows


def _central(start: int, end: int, n_poses: int) -> tuple[int, int]:
    """The positions of the poses a window bounds: with ``CENTRAL_ONLY``, its middle
    ``WINDOW_POSES - WINDOW_OVERLAP`` (the first and last windows reach the ends of the
    chain), so each pose is bounded by the one window where it has the most neighbours on
    both sides."""
    if not CENTRAL_ONLY:
        return start, end
    margin = WINDOW_OVERLAP // 2
    low = start + margin if start > 0 else 0
    high = end - (WINDOW_OVERLAP - margin) if end < n_poses else n_poses
    return low, high


def _bounded(
    targets: np.ndarray,
    poses: np.ndarray,
    low: int,
    high: int,
    landmarks: np.ndarray,
    landmark_x: np.ndarray,
) -> np.ndarray:
    """The ``targets`` a window bounds, in LP order (see ``Window.bounded``): the
    coordinates of its poses at positions ``low`` to ``high - 1`` and of the ``landmarks``.
    """
    k = np.searchsorted(poses, targets, side="right") - 1
    offset = targets - poses[np.maximum(k, 0)]
    is_pose = (k >= 0) & (offset <= 2)  # x, y, theta of a pose are consecutive variables
    kind = np.where(is_pose, offset, np.where(np.isin(targets, landmark_x), 0, 1))
    keep = np.where(is_pose, (k >= low) & (k < high), np.isin(targets, landmarks))
    order = np.lexsort((targets, kind))
    return targets[order[keep[order]]]


def _signature(lo: np.ndarray, hi: np.ndarray, variables: np.ndarray) -> float:
    """Mean of the logarithms of the finite, non-zero widths: it drops by about g when
    every variable shrinks by the fraction g."""
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        logs = np.log(hi[variables] - lo[variables])
    logs = logs[np.isfinite(logs)]
    return float(np.mean(logs)) if logs.size else 0.0


WIDTH_CAP = 1e300
"""Each finite width counts at most this much in a round's total (a measure of progress
only), so that widths near the largest double do not overflow the sum."""


def _total_width(lo: np.ndarray, hi: np.ndarray, variables: np.ndarray) -> float:
    with np.errstate(invalid="ignore", over="ignore"):
        widths = hi[variables] - lo[variables]
    return float(np.sum(np.minimum(widths[np.isfinite(widths)], WIDTH_CAP)))


class _Propagator:
    """Propagation over the whole graph with work arrays allocated once (a call costs what
    it touches, not the size of the graph)."""

    def __init__(self, arrays: Arrays, rtol: float, max_rounds: int) -> None:
        n = arrays.factors.shape[0]
        self.arrays, self.rtol, self.max_rounds = arrays, rtol, max_rounds
        self.queue = np.empty(n + 1, dtype=np.int64)
        self.state = np.zeros(n, dtype=np.int8)
        self.memory = fresh_memory(n)
        self.applied = np.empty(n, dtype=np.int64)

    def __call__(
        self, lo: np.ndarray, hi: np.ndarray, touched: np.ndarray, max_applications: int = 2**62
    ) -> tuple[Status, int]:
        a = self.arrays
        status, count, _ = propagate_buffered(
            lo, hi, a.factors, a.head, a.entry_factor, a.entry_next, touched, self.rtol,
            self.max_rounds, max_applications, self.queue, self.state, self.memory,
            self.applied, False,
        )  # fmt: skip
        return Status(status), count


def polytope_rounds(
    arrays: Arrays,
    lo: np.ndarray,
    hi: np.ndarray,
    rtol: float,
    max_rounds: int,
    progress: Callable[[int, int], None] | None,
    deadline: Budget | None,
    report: StrengthenReport,
    threads: int | None = None,
) -> tuple[Status, int, bool]:
    """Sweeps of the polytope-hull operator along the chain, forward then backward, until
    they stall.

    Before a window's LPs its factors are propagated (capped, see ``LOCAL_SPAN``), so each
    window starts from what the previous one found. A bound whose last LP moved it by less
    than ``STALE_GAIN`` of its width is *stale*: not solved again until its window's boxes
    have shrunk by ``UNSTALE_SHRINK`` since that window's last LPs, or the next full sweep
    (every ``FULL_ROUND_EVERY``-th). On a long log the windows are cut into parts swept
    concurrently, each on a copy of the bounds, the copies then intersected
    (:mod:`.parts`; the boxes do not depend on ``threads``: None, as many as
    :func:`.parts.default_threads`). After each sweep the whole graph is propagated.
    Returns ``(status, applications, finished)``; ``finished`` is False when the deadline
    cut the sweeps short (the boxes are then propagated to the fixpoint all the same).
    """
    windows = chain_windows(arrays.factors)
    if not windows:
        return Status.CONSISTENT, 0, True
    propagate = _Propagator(arrays, rtol, max_rounds)
    everything = np.arange(arrays.factors.shape[0], dtype=np.int64)
    applications = 0
    targets = np.unique(np.concatenate([w.targets for w in windows]))
    width = _total_width(lo, hi, targets)
    ranges = partition(len(windows))
    parts = [
        Part(r, len(lo), propagate if len(ranges) == 1 else _Propagator(arrays, rtol, max_rounds))
        for r in ranges
    ]
    warm = [WarmStarts() for _ in windows]
    signature = np.full(len(windows), -np.inf)
    for round_index in range(MAX_LP_ROUNDS):
        full = round_index % FULL_ROUND_EVERY == 0
        reuse = round_index >= REUSE_FROM and len(windows) >= REUSE_MIN_WINDOWS
        sweep = partial(
            _sweep_part, windows=windows, warm=warm, signature=signature,
            forward=round_index % 2 == 0, full=full, reuse=reuse,
            progress=_progress(progress, round_index, len(windows), len(parts)),
        )  # fmt: skip
        if len(parts) == 1:
            parts[0].budget = deadline
            consistent, empty = sweep(parts[0], lo, hi), False
        else:
            for part in parts:
                part.budget = None if deadline is None else deadline.alone(1.0 / len(parts))
            if threads is None:  # decided once, before this process adds to the load
                threads = default_threads()
            consistent, empty = run_parts(parts, lo, hi, sweep, max(1, int(threads)))
            for part in parts:
                if deadline is not None and part.budget is not None:
                    spend(deadline, part.budget.meter.spent)
                    if part.budget.meter.bound is not None:
                        deadline.meter.note(part.budget.meter.bound)
        for part in parts:
            report.lp.add(part.lp)
            part.lp = LpStatistics()
            applications += part.applications
            part.applications = 0
        if not consistent or empty:
            return Status.INCONSISTENT, applications, True
        report.lp_rounds += 1
        status, count = propagate(lo, hi, everything)
        applications += count
        spend(deadline, count * COSTS["operator"])
        if status is Status.INCONSISTENT:
            return Status.INCONSISTENT, applications, True
        if any(part.cut for part in parts):
            return Status.CONSISTENT, applications, False
        new_width = _total_width(lo, hi, targets)
        if new_width > width * (1.0 - MIN_GAIN):
            break
        if expired(deadline) and round_index + 1 < MAX_LP_ROUNDS:
            return Status.CONSISTENT, applications, False
        width = new_width
    return Status.CONSISTENT, applications, True


def _progress(
    progress: Callable[[int, int], None] | None, round_index: int, n_windows: int, n_parts: int
) -> Callable[[int], None] | None:
    """The first part's step, reported as the sweeps' progress (the parts advance at about
    the same pace)."""
    if progress is None:
        return None
    total = MAX_LP_ROUNDS * n_windows

    def report(step: int) -> None:
        progress(round_index * n_windows + min(step * n_parts, n_windows), total)

    return report


def _sweep_part(
    part: Part,
    lo: np.ndarray,
    hi: np.ndarray,
    *,
    windows: list[Window],
    warm: list[WarmStarts],
    signature: np.ndarray,
    forward: bool,
    full: bool,
    reuse: bool,
    progress: Callable[[int], None] | None,
) -> bool:
    """One sweep of ``part``'s windows over ``lo`` / ``hi`` (narrowed in place); False when
    the graph is proven inconsistent. ``part.cut`` says whether the deadline stopped it."""
    if full:
        part.stale_lo[:] = False
        part.stale_hi[:] = False
    skipped = part.lp.skipped
    part.cut = False
    for step, w in enumerate(part.order(forward)):
        if part.abandon:
            part.cut = True
            break
        if progress is not None and part.first:
            progress(step)
        visited = _visit(part, windows[w], warm[w], signature, w, lo, hi, reuse, part.budget)
        if visited is None:
            part.cut = True
            break
        if not visited:
            return False
    part.cut = part.cut or part.lp.skipped > skipped
    return True


def _visit(
    part: Part,
    window: Window,
    warm: WarmStarts,
    signature: np.ndarray,
    w: int,
    lo: np.ndarray,
    hi: np.ndarray,
    reuse: bool,
    deadline: Budget | None,
) -> bool | None:
    """One window's propagation and LPs, narrowing ``lo`` / ``hi`` in place with the
    ``part``'s buffers and stale marks. False: the graph is proven inconsistent; None: the
    deadline passed before the window's LPs."""
    stale_lo, stale_hi = part.stale_lo, part.stale_hi
    if _signature(lo, hi, window.targets) < signature[w] - UNSTALE_SHRINK:
        stale_lo[window.targets] = False
        stale_hi[window.targets] = False
    if reuse:
        lower, upper = window.bounded, window.bounded[::-1]
    else:
        lower = window.bounded[~stale_lo[window.bounded]]
        upper = window.bounded[~stale_hi[window.bounded]][::-1]
    if lower.size == 0 and upper.size == 0:
        return True
    if expired(deadline):
        return None
    status, count = part.propagate(lo, hi, window.indices, LOCAL_SPAN * len(window.indices))
    part.applications += count
    spend(deadline, count * COSTS["operator"])
    if status is Status.INCONSISTENT:
        return False
    old_lo, old_hi = lo[window.targets], hi[window.targets]
    tightened = tighten(
        window.rows, lo, hi, lower, warm, deadline=deadline, statistics=part.lp,
        upper_targets=upper, reuse=reuse,
    )  # fmt: skip
    if tightened.is_empty:
        return False
    with np.errstate(invalid="ignore", over="ignore"):  # widths past the largest double: inf
        slack = STALE_GAIN * (old_hi - old_lo)
        moved_lo = (lo[window.targets] - old_lo > slack) | (
            np.isinf(slack) & (lo[window.targets] > old_lo)
        )
        moved_hi = (old_hi - hi[window.targets] > slack) | (
            np.isinf(slack) & (hi[window.targets] < old_hi)
        )
    stale_lo[lower] = ~moved_lo[np.searchsorted(window.targets, lower)]
    stale_hi[upper] = ~moved_hi[np.searchsorted(window.targets, upper)]
    signature[w] = _signature(lo, hi, window.targets)
    return True
