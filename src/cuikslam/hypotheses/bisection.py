"""Deciding one hypothesis by bisection: split its box until every part is proven empty.

The search leaves a hypothesis ``not refuted`` when narrowing its whole box finds no
contradiction. That box is wide, and a contradiction may hold in each half of it without
showing in the whole (the relaxations lose precision with width). Bisection splits the
box along its widest pose or landmark variable, narrows each half to the fixpoint of the
hypothesis' own constraints (its factor rows, negative information included), and
continues on what is left. When every part is proven empty, the hypothesis is **proven
impossible**: the parts cover the box, which holds every solution.

It stops at its time or work budget, or when it runs out of parts; it never proves a
hypothesis consistent (that takes a verified witness, :mod:`.witness`), but it hands the
parts that survive longest to the witness search as starting boxes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cuikslam.budget import COSTS, SCHEDULE, Budget, expired, spend
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL, Arrays, narrow

__all__ = ["Bisection"]

HEADING_SCALE = 10.0
"""Metres a radian of heading counts for when choosing the widest variable (a heading
error moves what a pose sees 10 m away by about this much per radian)."""
APPLICATIONS_PER_PART = 200_000
"""Work budget of one part's narrowing (stopping early is sound, only weaker)."""
MIN_PENDING = 16
"""Parts a bisection may always keep waiting. Beyond that and its share of waiting parts
(:meth:`~cuikslam.budget.Schedule.pending_parts`: 1/8 of its parts), it gives up: the
hypothesis is not refuted (sound), its deepest part is kept for the witness search. Each
waiting part is a copy of every bound: the 100 survivors of a 200-pose log (Lost in the
Woods with a surveyed map), 327 parts each, held 1.7 GB before this limit."""


@dataclass
class Bisection:
    """A resumable bisection of one hypothesis' box.

    Parameters
    ----------
    lo, hi : ndarray
        The hypothesis' narrowed bounds (every variable of its graph).
    arrays : Arrays
        Its factor rows, linked (see :meth:`SharedGraph.standalone`).
    poses : ndarray of int
        x variables of its poses; ``(x, y, theta)`` are consecutive.
    landmarks : ndarray of int
        x variables of its landmarks; ``(x, y)`` are consecutive.
    """

    lo: np.ndarray
    hi: np.ndarray
    arrays: Arrays
    poses: np.ndarray
    landmarks: np.ndarray
    parts: list[tuple[np.ndarray, np.ndarray]] = field(default_factory=list)
    unsplit: int = 0
    """Parts with no finite variable left to split (not refuted: the hypothesis stands)."""
    last_unsplit: tuple[np.ndarray, np.ndarray] | None = None
    """The latest of them, kept for the witness search (one, so memory stays bounded)."""
    refuted_parts: int = 0
    narrowed_parts: int = 0
    gave_up: bool = False
    """Too many parts waited at once (see ``MIN_PENDING``): the hypothesis stands."""

    def __post_init__(self) -> None:
        self.parts = [(self.lo.copy(), self.hi.copy())]
        xs = np.concatenate([self.poses, self.poses + 1, self.landmarks, self.landmarks + 1])
        ts = self.poses + 2
        self._split_vars = np.concatenate([xs, ts])
        self._scale = np.concatenate([np.ones(len(xs)), np.full(len(ts), HEADING_SCALE)])

    @property
    def refuted(self) -> bool:
        """True when every part is proven empty: the hypothesis is impossible."""
        return not self.parts and not self.unsplit

    @property
    def exhausted(self) -> bool:
        """True when no part is left to split (refuted, or only unsplittable parts)."""
        return not self.parts

    def run(self, deadline: Budget | None, max_parts: int, max_pending: int | None = None) -> None:
        """Split parts and narrow the halves, up to ``max_parts`` narrowed halves (fewer at
        ``deadline``); give up when more than ``max_pending`` parts wait."""
        stop = self.narrowed_parts + max_parts
        while self.parts and self.narrowed_parts < stop:
            if expired(deadline):
                return
            lo, hi = self.parts.pop()
            var = self._widest(lo, hi)
            if var < 0:
                self.unsplit += 1
                self.last_unsplit = (lo, hi)
                continue
            mid = 0.5 * lo[var] + 0.5 * hi[var]
            halves = []
            for a, b in ((lo[var], mid), (mid, hi[var])):
                plo, phi = lo.copy(), hi.copy()
                plo[var], phi[var] = a, b
                if self._narrow(plo, phi, var, deadline):
                    halves.append((plo, phi))
                else:
                    self.refuted_parts += 1
            # depth first, the half with the smaller box on top: parts stay few
            halves.sort(key=lambda p: -self._size(*p))
            self.parts.extend(halves)
            if max_pending is not None and len(self.parts) > max_pending:
                self.give_up()
                return

    def give_up(self) -> None:
        """Stop for good, the hypothesis not refuted; keep only the deepest part."""
        self.last_unsplit = self.best()
        self.unsplit += len(self.parts)
        self.parts = []
        self.gave_up = True

    def best(self) -> tuple[np.ndarray, np.ndarray] | None:
        """The most recently narrowed part (the deepest), or None when all are refuted."""
        if self.parts:
            return self.parts[-1]
        return self.last_unsplit

    def _narrow(self, lo: np.ndarray, hi: np.ndarray, var: int, deadline: Budget | None) -> bool:
        """Narrow a part after ``var`` was split, spending its work; False when it is
        proven empty."""
        a = self.arrays
        self.narrowed_parts += 1
        result = narrow(
            a, lo, hi, a.factors_of(var), DEFAULT_RTOL, DEFAULT_ROUNDS, APPLICATIONS_PER_PART
        )
        spend(deadline, COSTS["bisection_part"] + COSTS["operator"] * result.applications)
        return not result.is_empty

    def _widest(self, lo: np.ndarray, hi: np.ndarray) -> int:
        """The pose or landmark variable to split: the widest (headings scaled), or -1 when
        none is finite and wider than a few ulps."""
        v = self._split_vars
        with np.errstate(invalid="ignore", over="ignore"):
            width = (hi[v] - lo[v]) * self._scale
            mid = 0.5 * lo[v] + 0.5 * hi[v]
        ok = np.isfinite(width) & (mid > lo[v]) & (mid < hi[v])
        if not np.any(ok):
            return -1
        width = np.where(ok, width, -1.0)
        return int(v[int(np.argmax(width))])

    def _size(self, lo: np.ndarray, hi: np.ndarray) -> float:
        v = self._split_vars
        with np.errstate(invalid="ignore", over="ignore"):
            width = np.nan_to_num((hi[v] - lo[v]) * self._scale, posinf=math.inf)
        return float(np.sum(np.minimum(width, 1e6)))


FIRST_ROUND_PARTS = 8
"""Parts each hypothesis narrows in the first round (then twice as many each round)."""


def refute_by_bisection(
    bisections: list[Bisection],
    deadline: Budget | None,
    max_parts: int,
    max_total_parts: int | None = None,
) -> list[bool]:
    """Which of ``bisections`` end proven impossible, sharing one budget round-robin.

    Each bisection may narrow ``max_parts`` parts, and no more than its even share of
    ``max_total_parts``; so, without a deadline, what each one proves does not depend on
    the others, and the bisections may be split among workers with the same result
    (:func:`allotment` gives the share). Each round gives every open bisection its quota
    (8 parts, then twice as many each round), so that the cheap refutations (a part or two)
    come first when the ``deadline`` cuts the rounds short. A bisection whose waiting parts
    outgrow the schedule's share of its parts gives up (memory stays bounded).
    """
    most = allotment(len(bisections), max_parts, max_total_parts)
    pending = max(MIN_PENDING, SCHEDULE.pending_parts(most))
    quota = FIRST_ROUND_PARTS
    while not expired(deadline):
        open_ = [b for b in bisections if not b.exhausted and b.narrowed_parts < most]
        if not open_:
            break
        for b in open_:
            b.run(deadline, min(quota, most - b.narrowed_parts), pending)
        quota *= 2
    return [b.refuted for b in bisections]


def allotment(n: int, max_parts: int, max_total_parts: int | None) -> int:
    """Parts each of ``n`` bisections may narrow: ``max_parts``, and at most an even share
    of ``max_total_parts``."""
    if max_total_parts is None or n == 0:
        return max_parts
    return min(max_parts, max_total_parts // n)
