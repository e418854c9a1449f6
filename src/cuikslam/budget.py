"""Budgets: every stage of a solve that could run long stops when its share is spent.

A solve's budget is counted in *work units*, not seconds, so that the same log, options and
version give the same result on any machine and at any load. Each stage spends units as it
works (:data:`COSTS` says what one unit is worth in each), checks :func:`expired` between
its units of work (an LP, a search node, a residual evaluation) and, once it has, stops with
whatever *sound* result it has: boxes narrowed so far (every narrowing step keeps every
solution, so stopping early only leaves boxes wider), or a hypothesis left ``not refuted``
(never claimed proven). It says so in its report, so the result is honest about what was
reached.

A wall-clock cap (``time_budget``, seconds) may be set as well: the first limit reached
stops the stage, and :attr:`Meter.bound` records which one did. When the clock binds, the
result depends on the machine and may differ from run to run; the result says so.

A :class:`Budget` is passed to the stages as their ``deadline`` argument (None: no limit).
:func:`cuikslam.solver.solve` makes one per solve; each stage asks :data:`SCHEDULE` (a
:class:`Schedule`) for its share, and nothing else decides one. The table of
``docs/concepts/budgets.md`` says which stage gets what, and why.

Examples
--------
>>> budget = Budget.start(work=100)
>>> stage = portion(budget, 0.5)
>>> spend(stage, 60)
>>> expired(stage), expired(budget), budget.meter.spent, budget.meter.bound
(True, False, 60.0, 'work')
>>> SCHEDULE.share(Budget.start(work=1000), "search").left
800.0
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Literal, get_args

__all__ = [
    "COSTS",
    "DEFAULT_WORK_BUDGET",
    "ONLINE_WORK_PER_POSE",
    "SCHEDULE",
    "SEARCH_WORK_PER_POSE",
    "WALK_RESERVE_PER_POSE",
    "WORK_PER_POSE",
    "Budget",
    "Meter",
    "OutOfTime",
    "Schedule",
    "Stage",
    "blas_single_thread",
    "capped",
    "deadline_after",
    "expired",
    "portion",
    "remaining",
    "spend",
    "walk_reserve_for",
    "work_budget_for",
]

DEFAULT_WORK_BUDGET = 2.0e6
"""Work units a solve may spend by default (``cuikslam solve --work-budget``), on top of
``WORK_PER_POSE`` per pose. Sized so that the seed's experiment with ids dropped is
decided (both survivors proven, ``lp`` reached) in about the time the former 2 s budget
took on the 2-core machine of ``docs/benchmarks.md``; ``benchmarks/bench_budget.py``
measures the units per second of each stage."""
WORK_PER_POSE = 1.0e5
"""Work units per pose of the log added to ``DEFAULT_WORK_BUDGET``: the ``lp`` level's
sweeps cost about the same per pose, so a long log gets work in proportion (its first
sweep reaches the end of the log; the result says ``lp (budget)`` when later sweeps were
cut)."""
SEARCH_WORK_PER_POSE = 3.0e5
"""Work units per pose instead of ``WORK_PER_POSE`` when some reading lacks its landmark
id (the correspondence search): sized so that the sparse 200-pose worlds of
``benchmarks/bench_always_answers.py`` complete in about a minute of this machine's CPU
(seeds 3 and 4 complete in 65 s and 36 s at 6.6e7 units, not at 2.2e7), while a search
that completes early spends no more for it."""
WALK_RESERVE_PER_POSE = 1.0e5
"""Work units per pose that only the search's walk of its tree may spend, beyond its share,
added to the ``auto`` budget of a log with a correspondence search: what the walk does not
spend of it is dropped, so a log whose walk ends early (the dense worlds, the seed's
experiment) spends no more for it, and the stages after the walk get the shares they would
have had without it. Sized since the search's windows narrowed in a local frame are
counted (2026-12-07; about half the walk's work): the sparse 200-pose worlds of
``benchmarks/bench_always_answers.py`` whose walk completed within 6.2e7 units before
(seed 3: 5.9e7 counted now) complete again."""
COSTS = {
    "operator": 1.0,
    "lp_entry": 1.5,
    "node": 200.0,
    "residual": 12.0,
    "evaluation": 100.0,
    "start": 1000.0,
    "bisection_part": 50.0,
    "lp_flop": 2.0e-4,
    "world_evaluation": 800.0,
    "jacobian_entry": 0.05,
    "factor_flop": 0.012,
    "verification": 1500.0,
    "interval_entry": 0.35,
    "product_entry": 4.0e-4,
}
"""Work units of one unit of work of each stage: a narrowing operator applied once; each
row and column of an LP solved (an LP of r rows and c columns costs ``(r + c) *
lp_entry``); a search node expanded (beside its propagation's operators); one residual
of a least-squares evaluation (witness search and fit), and the fixed cost of an
evaluation and of a start of the witness search; a part of a bisection narrowed (beside
its operators); a multiply-add of the dense LP kernel (:mod:`cuikslam.narrowing._simplex`:
its inverse of the active constraints, ``2 n**3``, and each pivot's update, ``2 n**2``
plus the matrix's entries, for n columns), whose cost grows faster than its LP's size on
the windows of a long log; the witness search's evaluation in its sparse world form
(:mod:`cuikslam.witness._world`): a fixed cost, and one per entry of its
Jacobian (computed, multiplied into the normal equations) and per (pose, landmark) pair
of the sensor's negative information, and a multiply-add of each sparse factorisation of
its normal equations (:func:`cuikslam.witness._levenberg.factor_work`, whose
fill grows faster than the log); its rigorous verification: a fixed cost, and one per
interval operation; and each entry of a dense Jacobian multiplied by a vector in the fit's
iterative steps (:func:`cuikslam.witness._dense.dense_least_squares`; 0.38 ns an entry).
Measured so that a unit is about a microsecond of this machine in each stage
(``benchmarks/bench_budget.py``, ``benchmarks/bench_witness.py``); what matters is only
that each is a fixed count of the same work on every machine."""
ONLINE_WORK_PER_POSE = 1_000.0
"""Work units an online session (:class:`cuikslam.online.Session`, ``cuikslam follow``)
may spend narrowing before it gives a finished pose's box, by default: about 1 ms here;
the rest of the narrowing follows the box. On a 2,000-pose log with a landmark in view at
nearly every pose, 1 % of the poses need more (up to about 30,000 units where a loop
closes); cut at 1,000, 34 of its 2,000 boxes are wider than at the fixpoint, by at most
2.5 % (measured in ``docs/online.md``)."""


class OutOfTime(Exception):
    """Raised inside a stage's inner loop when its budget is spent (caught by the stage)."""


@dataclass(eq=False)
class Meter:
    """The work a solve has spent, shared by every share of its budget."""

    spent: float = 0.0
    """Work units spent so far."""
    reserve: float = 0.0
    """Work units that only the walk (:meth:`Schedule.walking`) may spend beyond its
    share; dropped when it ends."""
    credit: float = 0.0
    """Work units the walk spent from ``reserve``: the other shares do not count them."""
    reserve_from: float | None = None
    """While the walk runs: the reading of :attr:`counted` beyond which its spending comes
    from ``reserve``."""
    bound: str | None = None
    """The first limit that stopped a stage: ``"work"``, ``"time"``, ``"interrupt"``
    (Ctrl-C) or None."""
    started: float = field(default_factory=time.perf_counter)
    stopped: bool = False
    """Set by :meth:`stop`."""
    _lock: threading.Lock = field(default_factory=threading.Lock, repr=False)

    def add(self, units: float) -> None:
        """Count ``units`` more (thread-safe: the ``lp`` sweeps of a long log run parts
        in threads)."""
        with self._lock:
            self.spent += units
            if self.reserve_from is not None and self.reserve > 0:
                moved = min(self.reserve, self.spent - self.credit - self.reserve_from)
                if moved > 0:
                    self.credit += moved
                    self.reserve -= moved

    @property
    def counted(self) -> float:
        """Work units the shares count: ``spent`` less the walk's reserve it spent."""
        return self.spent - self.credit

    def note(self, limit: str) -> None:
        """Record that ``limit`` stopped a stage (the first one recorded stays)."""
        if self.bound is None:
            self.bound = limit

    def stop(self) -> None:
        """Spend every budget on this meter at once (Ctrl-C: each stage stops at its next
        look, soundly, and the solve returns what it has)."""
        self.stopped = True
        self.note("interrupt")


@dataclass(frozen=True, eq=False)
class Budget:
    """What a stage may spend: the meter reading it stops at, and an optional wall clock.

    Attributes
    ----------
    meter : Meter
        The solve's meter, shared by every share of its budget.
    work : float
        The meter reading at which the stage stops (inf: no work limit).
    clock : float or None
        A :func:`time.perf_counter` value at which the stage stops (None: no time limit).
    walk : bool
        The walk's budget (:meth:`Schedule.walking`): ``work`` is a reading of
        ``meter.spent``, its reserve included; the other budgets' readings are of
        ``meter.counted``.
    """

    meter: Meter
    work: float = math.inf
    clock: float | None = None
    walk: bool = False

    @classmethod
    def start(
        cls, work: float | None = None, seconds: float | None = None, reserve: float = 0.0
    ) -> Budget:
        """A new budget of ``work`` units and ``seconds`` of wall clock (None: no limit),
        and ``reserve`` units more that only the walk may spend."""
        meter = Meter(reserve=max(0.0, float(reserve)))
        limit = math.inf if work is None else max(0.0, float(work))
        clock = None if seconds is None or math.isinf(seconds) else meter.started + seconds
        return cls(meter, limit, clock)

    @property
    def reading(self) -> float:
        """The meter's reading this budget's ``work`` is compared with."""
        return self.meter.spent if self.walk else self.meter.counted

    @property
    def unlimited(self) -> bool:
        """True when neither limit is set."""
        return self.work == math.inf and self.clock is None

    @property
    def left(self) -> float:
        """Work units left (never negative; inf without a work limit)."""
        return max(0.0, self.work - self.reading)

    def expired(self) -> bool:
        """True once the work is spent, the wall clock has passed, or the meter was stopped
        (recorded on the meter)."""
        if self.meter.stopped:
            return True
        if self.reading >= self.work:
            self.meter.note("work")
            return True
        if self.clock is not None and time.perf_counter() >= self.clock:
            self.meter.note("time")
            return True
        return False

    def share(self, fraction: float) -> Budget:
        """A budget for a stage that may use ``fraction`` of what is left of this one."""
        work = self.work
        if work != math.inf:
            work = self.reading + fraction * self.left
        clock = self.clock
        if clock is not None:
            now = time.perf_counter()
            clock = now + fraction * max(0.0, clock - now)
        return Budget(self.meter, work, clock, self.walk)

    def alone(self, fraction: float = 1.0) -> Budget:
        """A budget of ``fraction`` of what is left of this one, counted on a meter of its
        own: for work done in threads or on other processes, whose order of spending is not
        fixed, so that what each does is the same whatever the others do. The caller adds
        what it spent to this budget's meter when it is done."""
        return Budget(Meter(), fraction * self.left, self.share(fraction).clock)


def work_budget_for(n_poses: int, search: bool = False) -> float:
    """The default work budget of a log of ``n_poses`` poses (``search``: some of its
    readings lack their landmark id).

    >>> work_budget_for(10), work_budget_for(10, search=True)
    (3000000.0, 5000000.0)
    """
    return DEFAULT_WORK_BUDGET + (SEARCH_WORK_PER_POSE if search else WORK_PER_POSE) * n_poses


def walk_reserve_for(n_poses: int) -> float:
    """The reserve that only the search's walk may spend, added to the default budget of a
    log of ``n_poses`` poses with a correspondence search (:data:`WALK_RESERVE_PER_POSE`).

    >>> budget = Budget.start(work=1000, reserve=walk_reserve_for(0) + 500)
    >>> with SCHEDULE.walking(SCHEDULE.share(budget, "search")) as walk:
    ...     spend(walk, 1000)
    ...     expired(walk), budget.meter.credit
    (False, 280.0)
    >>> budget.left, budget.meter.spent, budget.meter.reserve
    (280.0, 1000.0, 0.0)
    """
    return WALK_RESERVE_PER_POSE * n_poses


def capped(deadline: Budget | None, units: float) -> Budget:
    """A budget of at most ``units`` more work, within ``deadline`` (on its meter, so that
    the work counts against it; a meter of its own without one).

    >>> stage = capped(None, 10.0)
    >>> spend(stage, 10.0)
    >>> expired(stage)
    True
    """
    if deadline is None:
        return Budget.start(work=units)
    work = min(deadline.work, deadline.reading + units)
    return Budget(deadline.meter, work, deadline.clock, deadline.walk)


def deadline_after(seconds: float | None) -> Budget | None:
    """A budget of ``seconds`` of wall clock and no work limit (None for None or infinity)."""
    if seconds is None or math.isinf(seconds):
        return None
    return Budget.start(seconds=max(0.0, float(seconds)))


def spend(deadline: Budget | None, units: float) -> None:
    """Count ``units`` of work against ``deadline`` (nothing without one)."""
    if deadline is not None and units:
        deadline.meter.add(units)


def remaining(deadline: Budget | None) -> float:
    """Seconds left on ``deadline``'s wall clock (infinity without one, never negative)."""
    if deadline is None or deadline.clock is None:
        return math.inf
    return max(0.0, deadline.clock - time.perf_counter())


def expired(deadline: Budget | None) -> bool:
    """True when ``deadline`` is set and spent (its work, or its wall clock)."""
    return deadline is not None and deadline.expired()


def portion(deadline: Budget | None, fraction: float) -> Budget | None:
    """A budget for a stage that may use ``fraction`` of what ``deadline`` has left.

    Parameters
    ----------
    deadline : Budget or None
        The overall budget (None: no limit, and None is returned).
    fraction : float
        Between 0 and 1.

    Returns
    -------
    Budget or None
        A share on the same meter.
    """
    if deadline is None:
        return None
    return deadline.share(fraction)


Stage = Literal[
    "strengthen",
    "search",
    "walk",
    "dive",
    "guess",
    "bisection",
    "early_proof",
    "guess_proof",
    "fit",
]
"""The stages of a solve that get a share of the budget (the fields of :class:`Schedule`
that are fractions)."""


@dataclass(frozen=True)
class Schedule:
    """The one place that decides how a solve's budget is shared among its stages.

    Each stage asks for its budget with :meth:`share` (a fraction of what is left of the
    budget it is given, when it starts: what a stage does not spend is left to the
    stages after it) or, for a branching node's ``lp`` window, :meth:`branch_node`. The
    values are those the solver has always used; ``docs/concepts/budgets.md`` tabulates
    them with the reason for each.

    Examples
    --------
    >>> budget = Budget.start(work=1000)
    >>> search = SCHEDULE.share(budget, "search")
    >>> walk = SCHEDULE.share(search, "walk")
    >>> search.left, walk.left, SCHEDULE.share(walk, "dive").left
    (800.0, 720.0, 432.0)
    >>> SCHEDULE.share(None, "fit") is None, SCHEDULE.pending_parts(512)
    (True, 64)
    >>> SCHEDULE.share(budget, "witness")
    Traceback (most recent call last):
    ...
    ValueError: no stage 'witness' in the schedule; the stages are strengthen, search, ...
    """

    strengthen: float = 0.7
    """Known correspondence: the stronger level, of what the fixpoint left; the witness
    search gets the rest (and whatever the level did not need)."""
    search: float = 0.8
    """Unknown correspondence: the correspondence search with its survivors' bisection
    and stronger level, of the solve's budget; the witness search gets the rest."""
    walk: float = 0.9
    """The search's walk of the tree (with its dive), of the search's share, and the
    budget's reserve (:meth:`walking`): the rest, with what the walk did not spend,
    decides its survivors (bisection, the stronger level), even when the walk is cut
    short. A dive that found nothing goes on with this share of the search's share. 0.7
    until the search's local-frame windows were counted (2026-12-07), which added about
    half to the walk's work: completing the walk is what decides most logs."""
    dive: float = 0.6
    """The dive (a leaf early, :mod:`cuikslam.hypotheses.dive`), of the walk's share: the
    exhaustive walk takes back the dive's expansions, so none of it is wasted."""
    guess: float = 0.5
    """The guess that decides a scan at a time (:mod:`cuikslam.hypotheses.guess`), of the
    dive's share; the dive gets what it leaves, and runs only when the guess is not
    proven."""
    bisection: float = 0.5
    """The survivors' bisection, of what the walk left; the stronger level the rest."""
    early_proof: float = 0.2
    """The witness search on the dive's leaf while the search goes on, of what is left of
    the solve's budget when the leaf is found: a proven hypothesis early."""
    guess_proof: float = 0.1
    """The witness search on the guess's leaf, of the early proof's share: a proof of the
    true correspondence of a 1,000-pose sparse world takes about a twentieth of it, and a
    wrong guess that nothing refuted would spend it all before the dive."""
    fit: float = 0.5
    """The least-squares fit that ranks the reported survivors, of what is left of the
    solve's budget when the search ends."""
    bisection_pending: int = 8
    """A bisection keeps at most ``1 / bisection_pending`` of its parts waiting (memory
    stays bounded; parts, not work units: :meth:`pending_parts`)."""
    branch_node_work: float = 5.0e5
    """Work units at most of the ``lp`` level on a branching node's window, within the
    search's share, and also when the solve has no budget: cut short, the window is
    still sound, and no one ambiguous node can hold up the search (:meth:`branch_node`;
    about the second it was given when budgets were seconds)."""

    def share(self, budget: Budget | None, stage: Stage) -> Budget | None:
        """The budget of ``stage``: its fraction of what is left of ``budget``, on the
        same meter (None without a budget)."""
        if stage not in _STAGES:
            raise ValueError(
                f"no stage {stage!r} in the schedule; the stages are {', '.join(_STAGES)}"
            )
        return portion(budget, getattr(self, stage))

    @contextmanager
    def walking(self, budget: Budget | None) -> Iterator[Budget | None]:
        """The walk's share of ``budget`` (the search's), with its meter's reserve.

        Inside, what is spent beyond the walk's share (by the walk, its dive, and the
        early proof of the dive's leaf, which run inside it) comes from the reserve, which
        the other shares do not count; on leaving, what is left of the reserve is dropped:
        the stages after the walk get the shares they would have had without it.
        """
        share = self.share(budget, "walk")
        if share is None or share.meter.reserve <= 0:
            yield share
            return
        meter = share.meter
        meter.reserve_from = share.work
        extended = share.work - meter.counted + meter.reserve
        try:
            yield Budget(meter, meter.spent + extended, share.clock, walk=True)
        finally:
            meter.reserve_from = None
            meter.reserve = 0.0

    def branch_node(self, budget: Budget | None) -> Budget:
        """The budget of the ``lp`` level on one branching node's window: at most
        ``branch_node_work`` more units within ``budget`` (with none, of its own)."""
        return capped(budget, self.branch_node_work)

    def pending_parts(self, parts: int) -> int:
        """The parts a bisection of ``parts`` parts may keep waiting at once."""
        return parts // self.bisection_pending


_STAGES: tuple[str, ...] = get_args(Stage)
SCHEDULE = Schedule()
"""The schedule every solve follows."""


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
