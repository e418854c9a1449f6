"""An online session: records in as the robot drives, the newest pose's box out.

A :class:`Session` takes the records of a log one at a time, in time order, checked by
the same rules as a log file (:class:`~cuikslam.log.reader.OrderCheck`) and turned into
factors by the same path (:meth:`~cuikslam.graph.KinematicGraph.add_record`). A pose is
*finished* when a record reaches a later pose (an odometry or relative pose to a pose not
reached yet, or a prior on one) or when the input ends (:meth:`Session.finish`); its box
is then narrowed and returned (:class:`~.estimate.PoseEstimate`). The narrowing is
incremental: the records since the last finished pose wake only their own factors, and
the compiled propagation goes on from there only through the variables that shrink
(:class:`~.growing.GrowingGraph`). Every box holds the truth whenever every record holds
its own, as in a batch solve; only the order of the narrowing steps differs, so a box may
differ from the batch ``hull`` box within the propagation's tolerance (``rtol``).

From the first reading without a landmark id (or an ``outliers`` record) on, the session
keeps the live correspondence hypotheses instead (:class:`~.hypotheses.LiveHypotheses`),
updated at each finished pose; a pose's box is then the hull of theirs.
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Callable

import numpy as np

from cuikslam.budget import COSTS, ONLINE_WORK_PER_POSE, Budget
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.graph.variables import Variables
from cuikslam.log.reader import OrderCheck
from cuikslam.log.records import (
    ClassPrior,
    LandmarkPrior,
    Log,
    Observation,
    Odometry,
    OutlierBound,
    PosePrior,
    Record,
    RelativePose,
    SensorModel,
)
from cuikslam.narrowing.propagation import DEFAULT_RTOL, Status
from cuikslam.online.estimate import PoseEstimate
from cuikslam.online.growing import GrowingGraph
from cuikslam.online.hypotheses import LiveHypotheses
from cuikslam.online.window import WINDOW_POSES, tighten_window

__all__ = ["SETTLE_MARGIN_S", "SETTLE_STEP", "WINDOW_MARGIN_S", "WINDOW_WORK", "Session", "warm_up"]

WINDOW_WORK = 500_000.0
"""Work units the ``lp`` level may spend on the window of each finished pose at most (about
half a second here; its LPs stop there, soundly)."""
SETTLE_STEP = 1_000.0
"""Work units of each step of :meth:`Session.settle`, which checks the clock between
steps (about 1 ms here)."""
SETTLE_MARGIN_S = 0.002
"""Seconds before its ``until`` after which :meth:`Session.settle` starts no step: a step
started later could end after it (the caller would then be late for its next record)."""
WINDOW_MARGIN_S = 0.025
"""Seconds of its ``until`` that :meth:`Session.settle` keeps back from the ``lp`` window,
which looks at the clock only between batches of LPs and has a fixed cost of its own
(measured: up to 19 ms past a deadline on a 40-pose world at load 7)."""
WINDOW_TIMES = 20
"""The window starts before an ``until`` only when the time left exceeds the longest of
the last ``WINDOW_TIMES`` windows (wall clock) by ``WINDOW_MARGIN_S`` (by twice that
before the first), so that one cut short by its deadline is the exception."""


class Session:
    """Guaranteed boxes as the robot drives: add records as they arrive, get each pose's box
    when it is finished.

    Parameters
    ----------
    consistency : str
        ``"hull"`` (default): the fixpoint of the narrowing operators. ``"lp"``: also,
        once a pose is finished and its box given, the polytope-hull operator on the
        window of the last ``WINDOW_POSES`` finished poses (:mod:`.window`), within
        ``WINDOW_WORK`` work units and the time :meth:`settle` is given; what it narrows
        (those poses, the landmarks they see) narrows the boxes given next. Known
        correspondence only (with unknown correspondence the level is ``hull``).
    rtol : float
        A variable that shrinks by less than this fraction of its width wakes no other
        factor (as in a batch solve).
    work_per_pose : float, optional
        Work units (:mod:`cuikslam.budget`) the narrowing may spend when a pose is
        finished, before its box is given (default
        :data:`~cuikslam.budget.ONLINE_WORK_PER_POSE`); what it could not
        do waits for :meth:`settle` or the next pose (sound either way: a box given
        earlier is only wider). None: to the fixpoint every time.
    path : str
        Where the records come from, for messages.

    Examples
    --------
    >>> from cuikslam.log.records import Observation, Odometry, PosePrior
    >>> session = Session()
    >>> session.add(PosePrior(0, (0, 0), (0, 0), (0, 0)))
    >>> session.add(Observation(0, "post", (2.0, 2.1), (-0.01, 0.01), landmark="P"))
    >>> first = session.add(Odometry(0, 1, (0.0, 0.0), (1.0, 1.1)))  # pose 0 is finished
    >>> first.pose, first.box.tolist()
    (0, [[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    >>> session.add(Observation(1, "post", (0.9, 1.0), (-0.01, 0.01), landmark="P"))
    >>> last = session.finish()  # the end of the input finishes pose 1
    >>> last.pose, last.box[0].round(3).tolist(), last.hypotheses
    (1, [1.0, 1.1], 1)
    """

    def __init__(
        self,
        *,
        consistency: str = "hull",
        rtol: float = DEFAULT_RTOL,
        work_per_pose: float | None = ONLINE_WORK_PER_POSE,
        path: str = "<session>",
    ) -> None:
        if consistency not in ("hull", "lp"):
            raise ValueError(f"an online session narrows at level hull or lp, not {consistency!r}")
        self.consistency = consistency
        self.path = path
        self.rtol = rtol
        self._window_due = False
        self._window_s: deque[float] = deque(maxlen=WINDOW_TIMES)
        """Wall-clock seconds of the last windows."""
        self._grow_s = 0.0
        """Wall-clock seconds the arrays took to grow last (the next, twice as large, is
        started with four times that left)."""
        self._pose_xs: set[int] = set()
        self.work_per_pose = work_per_pose
        self._check = OrderCheck(path)
        self._records: list[Record] = []
        self._live: LiveHypotheses | None = None
        """With unknown correspondence (or an outliers record), the live hypotheses."""
        self._search_again = False
        self._sensor = False
        self._finished_set: set[int] = set()
        self._graph = KinematicGraph()
        self._grown = GrowingGraph(rtol)
        self._touched: list[np.ndarray] = []
        self._deferred = np.zeros(0, dtype=np.int64)
        self._pending_lines: list[int] = []
        self.newest: int | None = None
        """The pose the log reached last (not finished yet), or None."""
        self.finished: list[int] = []
        """The finished poses, in the order they were finished."""
        self.refuted: str | None = None
        """Once the records are proven inconsistent, the message saying so (then no box is
        given any more: there is no solution)."""
        self.records = 0
        """Records added."""
        self.applications = 0
        """Narrowing operators applied, over the whole session."""

    # ------------------------------------------------------------------ input
    def add(self, record: Record, *, received: float | None = None) -> PoseEstimate | None:
        """Add the next record of the log; returns the box of the pose it finishes, if any.

        Parameters
        ----------
        record : Record
            The next record, in time order.
        received : float, optional
            When the record arrived (:func:`time.perf_counter`), from which the latency of
            the box is counted; by default, now.

        Raises
        ------
        InputFileError
            When the record breaks a rule of the log format given the records before it
            (naming ``path`` and the record's line).
        """
        received = time.perf_counter() if received is None else received
        if self.refuted is not None:
            return None
        new_pose = self._reaches_new_pose(record)
        self._check(record)
        self.records += 1
        finished = None
        if new_pose:
            finished = self._finish_newest(received)
            self.newest = record.pose if isinstance(record, PosePrior) else record.target
        self._records.append(record)  # after: a finished pose's update stops before it
        self._add(record)
        return finished

    def finish(self, *, received: float | None = None) -> PoseEstimate | None:
        """The end of the input: the box of the last pose (None when it is finished already,
        or the log is proven inconsistent)."""
        received = time.perf_counter() if received is None else received
        estimate = self._finish_newest(received)
        self.newest = None
        return estimate

    def settle(self, until: float | None = None) -> bool:
        """Narrow what the records so far still owe (work a limit deferred, records not
        narrowed yet) to the fixpoint, in steps of ``SETTLE_STEP`` work units, then
        grow the graph's arrays when they are nearly full (so that a record seldom has to
        wait for it; :meth:`.growing.GrowingGraph.grow`), then the ``lp`` window. With
        ``until`` (a :func:`time.perf_counter` value), start no step within
        ``SETTLE_MARGIN_S`` of it (nor the arrays' growth within four times the time the
        last one took), and the ``lp`` window only when the time left is
        ``WINDOW_MARGIN_S`` more than the longest of the last windows took, to end
        ``WINDOW_MARGIN_S`` before it at the latest (see ``WINDOW_TIMES``). Returns True at
        the fixpoint."""
        while self._live is None and self.refuted is None:
            grow = self._grown.nearly_full
            if not (self._touched or len(self._deferred) or self._window_due or grow):
                return True
            left = math.inf if until is None else until - time.perf_counter()
            if self._touched or len(self._deferred):
                if left <= SETTLE_MARGIN_S:
                    return False
                self._narrow(SETTLE_STEP)
            elif grow:
                if left <= SETTLE_MARGIN_S + 4 * self._grow_s:
                    return False
                started = time.perf_counter()
                self._grown.grow()
                self._grow_s = time.perf_counter() - started
            elif left <= WINDOW_MARGIN_S + max(self._window_s, default=WINDOW_MARGIN_S):
                return False
            else:
                started = time.perf_counter()
                self._tighten_window(left - WINDOW_MARGIN_S)
                self._window_s.append(time.perf_counter() - started)
        return True

    def _tighten_window(self, seconds: float) -> None:
        """The ``lp`` level on the window of the last finished poses (see ``consistency``),
        for at most ``seconds`` (``math.inf``: no time limit) and ``WINDOW_WORK``."""
        self._window_due = False
        poses = self.finished[-WINDOW_POSES:]
        deadline = Budget.start(WINDOW_WORK, seconds)
        xs = np.array([self._graph.pose_index(p) for p in poses], dtype=np.int64)
        shrank, consistent = tighten_window(self._grown, xs, self._pose_xs, deadline)
        if not consistent:
            self._refute()
        elif len(shrank):
            self._touched.append(self._grown.factors_of(shrank))

    # ------------------------------------------------------------------ output
    @property
    def has_poses(self) -> bool:
        """True once a record reached a pose (which only a prior can do first)."""
        return bool(self._check.reached)

    @property
    def hypotheses(self) -> int:
        """Correspondence hypotheses alive: 1 with known correspondence (0 once refuted)."""
        if self.refuted is not None:
            return 0
        return 1 if self._live is None or self._live.explorer is None else len(self._live)

    def assignments(self) -> list[list[str]]:
        """The landmark of each observation so far (log order) in each live hypothesis
        (with unknown correspondence, as of the last finished pose; see
        :meth:`.hypotheses.LiveHypotheses.assignments`)."""
        if self.refuted is not None:
            return []
        if self._live is None:
            return [[r.landmark for r in self._records if isinstance(r, Observation)]]
        return self._live.assignments()

    def pose_box(self, pose: int) -> np.ndarray:
        """The (3, 2) box of any pose reached so far, every record added so far narrowed in.

        With unknown correspondence, the hull of its boxes over the live hypotheses as of
        the last finished pose (the records since come in when the next pose is
        finished); before the first pose finished after the first reading without an id,
        its box from the records before that reading.

        Raises
        ------
        KeyError
            For a pose not reached yet (with unknown correspondence: not reached when the
            last pose was finished).
        ValueError
            Once the records are proven inconsistent (:attr:`refuted`).
        """
        self.settle()
        self._raise_if_refuted()
        if self._live is not None and self._live.explorer is not None:
            return self._live.pose_box(pose)
        if self._live is not None:
            # the first reading without an id came after this pose was finished, and no
            # pose since: the records before it, narrowed as they were, bound it soundly
            self._narrow()
            self._raise_if_refuted()
        i = self._graph.pose_index(pose)
        return np.stack([self._grown.lo[i : i + 3], self._grown.hi[i : i + 3]], axis=-1)

    def landmark_box(self, landmark: str) -> np.ndarray:
        """The (2, 2) box of a landmark named so far (see :meth:`pose_box`)."""
        self.settle()
        self._raise_if_refuted()
        if self._live is not None:
            raise ValueError(
                "with unknown correspondence a landmark is not the same in every hypothesis: "
                "see assignments()"
            )
        i = self._graph.landmark_index(landmark)
        return np.stack([self._grown.lo[i : i + 2], self._grown.hi[i : i + 2]], axis=-1)

    # ------------------------------------------------------------------ inside
    def _raise_if_refuted(self) -> None:
        if self.refuted is not None:
            raise ValueError(self.refuted)

    def _reaches_new_pose(self, record: Record) -> bool:
        """True when ``record`` will be the first to reach its pose."""
        match record:
            case PosePrior(pose=pose) | Odometry(target=pose) | RelativePose(target=pose):
                return pose not in self._check.reached
        return False

    def _finish_newest(self, received: float) -> PoseEstimate | None:
        if self.newest is None or self.refuted is not None:
            return None
        pose = self.newest
        if self._live is not None:
            self._live.update(Log(self._records, self.path), complete=self._search_again)
            self._search_again = False
            if self._live.refuted:
                self.refuted = (
                    f"{self.path}: every correspondence hypothesis is proven impossible "
                    f"(a proof), when pose {pose} was finished"
                )
                return None
            box = self._live.pose_box(pose)
        else:
            self._narrow(self.work_per_pose)
            if self.refuted is not None:
                return None
            i = self._graph.pose_index(pose)
            box = np.stack([self._grown.lo[i : i + 3], self._grown.hi[i : i + 3]], axis=-1)
        self.finished.append(pose)
        self._finished_set.add(pose)
        self._window_due = self.consistency == "lp" and self._live is None
        return PoseEstimate(pose, box, time.perf_counter() - received, self.hypotheses)

    def _add(self, record: Record) -> None:
        self._sensor = self._sensor or isinstance(record, SensorModel)
        if self._live is None and (
            isinstance(record, OutlierBound)
            or (isinstance(record, Observation) and record.landmark is None)
        ):
            self._live = LiveHypotheses(self.rtol)
        if self._live is not None:  # the records are kept, the search takes them at a pose
            if isinstance(record, Observation) and record.pose in self._finished_set:
                self._search_again = self._search_again or self._sensor
            return
        graph, grown = self._graph, self._grown
        graph.add_record(record)
        self._pending_lines.append(record.line)
        match record:
            case PosePrior(pose=pose) | Odometry(target=pose) | RelativePose(target=pose):
                self._pose_xs.add(graph.pose_index(pose))
        if graph.n_variables > grown.n_variables:
            grown.add_variables(*graph.domains(grown.n_variables))
        if graph.n_factors > grown.n_factors:
            self._touched.append(grown.add_factors(graph.factor_table(grown.n_factors)))
        match record:
            case PosePrior(pose=pose, x=x, y=y, theta=theta):
                self._meet(graph.pose_index(pose), 3, lambda v: v.meet_pose(0, x, y, theta))
            case LandmarkPrior(landmark=landmark, x=x, y=y):
                self._meet(graph.landmark_index(landmark), 2, lambda v: v.meet_point(0, x, y))
            case ClassPrior(landmark_class=cls, x=x, y=y) if x is not None and y is not None:
                for landmark, kind in zip(graph.landmark_ids, graph.landmark_classes, strict=True):
                    if kind == cls:
                        self._meet(
                            graph.landmark_index(landmark), 2, lambda v: v.meet_point(0, x, y)
                        )

    def _meet(self, first: int, n: int, meet: Callable[[Variables], None]) -> None:
        """Intersect the bounds of variables ``first .. first + n - 1`` as ``meet`` does on
        a :class:`~cuikslam.graph.variables.Variables` of them (headings modulo 2π), and
        wake the factors of those that shrink."""
        grown = self._grown
        old_lo, old_hi = grown.lo[first : first + n].copy(), grown.hi[first : first + n].copy()
        view = Variables(old_lo.tolist(), old_hi.tolist())
        meet(view)
        new_lo, new_hi = np.array(view.lo), np.array(view.hi)
        if not np.all(new_lo <= new_hi):
            self._refute()
            return
        grown.lo[first : first + n], grown.hi[first : first + n] = new_lo, new_hi
        changed = first + np.flatnonzero((new_lo != old_lo) | (new_hi != old_hi))
        if len(changed):
            self._touched.append(grown.factors_of(changed))

    def _narrow(self, work: float | None = None) -> None:
        """Narrow from every factor the records since the last call touched, then from
        those a work limit deferred before (a finished pose's own records go first),
        within ``work`` units (None: no limit)."""
        if self.refuted is not None:
            return
        if not (self._touched or len(self._deferred)):
            self._pending_lines = []
            return
        touched = np.concatenate([*self._touched, self._deferred])
        self._touched = []
        limit = 2**62 if work is None else max(1, int(work / COSTS["operator"]))
        result = self._grown.narrow(touched, limit)
        self.applications += result.applications
        self._deferred = result.deferred
        if result.status is Status.INCONSISTENT:
            self._refute()
        else:
            self._pending_lines = []

    def _refute(self) -> None:
        lines = [n for n in self._pending_lines if n > 0]
        where = f" (proven when the records of lines {min(lines)}-{max(lines)} came in)"
        self.refuted = (
            f"{self.path}: the log is inconsistent: its constraints contract to empty (a proof)"
            + (where if lines else "")
        )


def warm_up(unknown: bool = False, lp: bool = False) -> None:
    """Load the compiled kernels a session calls (from numba's cache, or compile them), so
    that the latency of the first pose does not include it: a session of two poses, with
    ``unknown`` one whose correspondence is unknown, with ``lp`` at level ``lp``."""
    for named in (True, False) if unknown else (True,):
        session = Session(consistency="lp" if lp and named else "hull")
        session.add(SensorModel(max_range=5.0, fov=3.0))
        session.add(PosePrior(0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)))
        session.add(Observation(0, "c", (1.0, 1.1), (0.0, 0.1), "A" if named else None))
        session.add(Odometry(0, 1, (0.0, 0.1), (1.0, 1.1)))
        session.add(PosePrior(1, (-5.0, 5.0), (-5.0, 5.0), (-1.0, 1.0)))
        session.add(Observation(1, "c", (0.0, 0.2), (0.0, 0.1), "A" if named else None))
        session.finish()
        session.settle()
