"""Following a log as it is written: lines from a file, a pipe or a growing file, fed to a
:class:`~.session.Session` as they come, or at the rate their time stamps say.

:func:`log_lines` reads the numbered lines (a file to its end, standard input until it
closes, or a growing file, like ``tail -f``, until it stops growing); :func:`follow` parses
each with the log reader (:func:`~cuikslam.log.reader.parse_log_line`), adds it to the
session and hands each finished pose's box to a callback. With a ``rate``, each record is
fed when its ``time`` falls due (``rate`` 1: the recorded pace; 2: twice as fast), and
the report says whether the session ever fell behind: whether the records of some instant
fell due before those of the previous instant were done.
"""

from __future__ import annotations

import gc
import math
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TextIO

import numpy as np

from cuikslam.errors import InputFileError
from cuikslam.log.reader import check_complete, parse_log_line
from cuikslam.online.estimate import PoseEstimate
from cuikslam.online.session import Session

__all__ = ["FollowReport", "Pacer", "follow", "log_lines"]

POLL_S = 0.02
"""How long a reader of a growing file sleeps when it finds no new line."""


def log_lines(
    stream: TextIO,
    *,
    path: str = "<stream>",
    wait: float | None = None,
    clock: Callable[[], float] = time.perf_counter,
) -> Iterator[tuple[int, str, float]]:
    """The lines of ``stream`` as ``(number, text, received)``, numbered from 1, with the
    :func:`time.perf_counter` value when each was read.

    Parameters
    ----------
    stream : TextIO
        A file or a pipe, read line by line (a pipe's lines come as they are written).
    path : str
        Its name, for messages.
    wait : float, optional
        Follow a growing file: at its end, wait for more, for up to ``wait`` seconds
        without a new line (``math.inf``: until interrupted). A last line without its
        newline is taken only when the waiting ends (it may be half-written).

    Raises
    ------
    InputFileError
        At a line that is not UTF-8 text.

    Examples
    --------
    >>> import io
    >>> [(n, text) for n, text, _ in log_lines(io.StringIO("a\\n\\nb"))]
    [(1, 'a\\n'), (2, '\\n'), (3, 'b')]
    """
    number = 0
    partial = ""
    idle_since = clock()
    while True:
        try:
            chunk = stream.readline()
        except UnicodeDecodeError as err:
            raise InputFileError(path, number + 1, "the line is not UTF-8 text") from err
        if chunk:
            idle_since = clock()
            partial += chunk
            if not partial.endswith("\n") and wait is not None:
                continue  # the writer is still on this line
            number += 1
            yield number, partial, clock()
            partial = ""
            continue
        if wait is None or clock() - idle_since >= wait:
            break
        time.sleep(POLL_S)
    if partial:
        yield number + 1, partial, clock()


@dataclass
class Pacer:
    """When each record falls due, replaying time stamps at ``rate`` times their pace.

    The first record with a time stamp is due at once; a record without one is due with
    the record before it; a time stamp earlier than the one before counts as that one.

    Examples
    --------
    >>> pacer = Pacer(rate=2.0)
    >>> [pacer.due(t, now=100.0) for t in (5.0, None, 6.0, 5.5, 9.0)]
    [100.0, 100.0, 100.5, 100.5, 102.0]
    """

    rate: float
    _start: tuple[float, float] | None = None
    _last: float = -math.inf

    def due(self, stamp: float | None, now: float) -> float:
        """The :func:`time.perf_counter` value at which a record stamped ``stamp`` is due
        (``now``: the present, which starts the clock at the first time stamp)."""
        if stamp is None:
            return now if self._start is None else self._wall(self._last)
        if self._start is None:
            self._start = (stamp, now)
        self._last = max(self._last, stamp)
        return self._wall(self._last)

    def _wall(self, stamp: float) -> float:
        assert self._start is not None
        return self._start[1] + (stamp - self._start[0]) / self.rate


@dataclass
class FollowReport:
    """What following a log did."""

    poses: int = 0
    """Poses whose box was given."""
    latencies_s: list[float] = field(default_factory=list)
    """Latency of each pose's box (:attr:`PoseEstimate.latency_s`), in order."""
    refuted: str | None = None
    """The message when the records were proven inconsistent (the follow then stopped)."""
    interrupted: bool = False
    """True when Ctrl-C ended the input."""
    instants: int = 0
    """With a rate: distinct time stamps fed."""
    late: int = 0
    """With a rate: instants whose records fell due before those of the previous instant
    were done (the session fell behind the recorded pace)."""
    worst_late_s: float = 0.0
    """With a rate: how long after it fell due the latest such instant could start."""
    worst_late_line: int = 0
    """With a rate: the line of the record that started that instant."""
    lags_s: list[float] = field(default_factory=list)
    """With a rate: for each instant, how long after it fell due its first record was
    fed (when on time, how late the wait for it woke up)."""

    def latency_percentile(self, q: float) -> float:
        """The ``q``-th percentile of the latencies (NaN without poses)."""
        return float(np.percentile(self.latencies_s, q)) if self.latencies_s else math.nan


def follow(
    lines: Iterator[tuple[int, str, float]],
    session: Session,
    on_pose: Callable[[PoseEstimate], None],
    *,
    rate: float | None = None,
    clock: Callable[[], float] = time.perf_counter,
    sleep: Callable[[float], None] = time.sleep,
) -> FollowReport:
    """Feed numbered log lines to ``session``; ``on_pose`` gets each finished pose's box.

    What a pose's work limit left of the narrowing, and at level ``lp`` the window
    (:meth:`Session.settle`), is done right after the pose's box is given, or, with a
    ``rate``, while the next record is not due. The records a session keeps live as long
    as it does, so while following, the objects of the process are moved out of the
    garbage collector's reach at each pose given (:func:`gc.freeze`; given back at the
    end): its full collections, whose cost grows with the log (200 ms halfway through Lost
    in the Woods), then do not stall a pose. The input ends with ``lines``, with Ctrl-C
    (the last pose is finished all the same, and ``interrupted`` is set), or once the
    records are proven inconsistent.

    Parameters
    ----------
    lines : iterator of (int, str, float)
        As :func:`log_lines` gives them.
    session : Session
        Where the records go; its ``path`` names the input in messages.
    on_pose : callable
        Called with each pose's box as the pose is finished, in order.
    rate : float, optional
        Replay the records' time stamps at this many times their pace (see
        :class:`Pacer`); None: as fast as they come.

    Raises
    ------
    InputFileError
        At the first line that breaks the log format (the boxes given so far stay true),
        or at the end of an input without records or without a pose prior.
    """
    report = FollowReport()
    pacer = Pacer(rate) if rate is not None else None
    last_stamp: float | None = None
    gc.freeze()  # what exists now, and each pose's records once given: see the docstring

    def give(estimate: PoseEstimate | None) -> None:
        if estimate is not None:
            report.poses += 1
            report.latencies_s.append(estimate.latency_s)
            on_pose(estimate)

    try:
        for number, text, received in lines:
            record = parse_log_line(text, number, session.path)
            if record is None:
                continue
            if pacer is not None:
                due = pacer.due(record.time, clock())
                session.settle(until=due)  # time to spare until the record falls due
                ready = clock()
                new_instant = record.time is not None and (
                    last_stamp is None or record.time > last_stamp
                )
                if new_instant:
                    report.instants += 1
                    last_stamp = record.time
                    if ready > due and report.instants > 1:
                        report.late += 1
                        if ready - due > report.worst_late_s:
                            report.worst_late_s, report.worst_late_line = ready - due, number
                if due > ready:
                    sleep(due - ready)
                if new_instant:
                    report.lags_s.append(max(0.0, clock() - due))
                received = due
            estimate = session.add(record, received=received)
            give(estimate)
            if estimate is not None:
                gc.freeze()
                if pacer is None:
                    session.settle()  # the box is out: now the rest of the narrowing
            if session.refuted is not None:
                report.refuted = session.refuted
                return report
    except KeyboardInterrupt:
        report.interrupted = True
    finally:
        gc.unfreeze()
    check_complete(session.records, session.has_poses, session.path)
    give(session.finish())
    report.refuted = session.refuted
    return report
