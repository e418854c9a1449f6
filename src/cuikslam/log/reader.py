"""Reading a log: JSON Lines text into a validated :class:`~cuikslam.log.records.Log`.

Every problem raises :class:`~cuikslam.errors.InputFileError` naming the file, the
line and what is wrong, because a log with a silent mistake yields a wrong map that is
still "guaranteed".
"""

from __future__ import annotations

import io
import json
import os
from collections.abc import Iterable
from typing import Any

from cuikslam._json import loads_object
from cuikslam.errors import InputFileError
from cuikslam.log._fields import Problem, record_from_json
from cuikslam.log.records import (
    RESERVED_LANDMARK_ID,
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

__all__ = [
    "OrderCheck",
    "check_complete",
    "parse_log_line",
    "parse_log_lines",
    "read_log_file",
    "reject_reserved_landmark_id",
]

_RESERVED = (
    f'landmark id "{RESERVED_LANDMARK_ID}" is reserved (hypotheses\' assignments mark '
    "outliers with it): rename it"
)


def reject_reserved_landmark_id(log: Log) -> None:
    """Refuse a log (read from a file or built in code) that names a landmark with the id
    :data:`~cuikslam.log.records.RESERVED_LANDMARK_ID`.

    Raises
    ------
    InputFileError
        Naming the log and the line of the first record naming that landmark.
    """
    for record in log.records:
        if getattr(record, "landmark", None) == RESERVED_LANDMARK_ID:
            raise InputFileError(log.path, getattr(record, "line", 0), _RESERVED)


def read_log_file(path: str | os.PathLike[str]) -> Log:
    """Read and validate the log at ``path`` (UTF-8 JSON Lines, see ``docs/log-format.md``).

    Raises
    ------
    InputFileError
        If the file cannot be read, is not UTF-8, or breaks the format.
    """
    name = os.fspath(path)
    try:
        with open(name, encoding="utf-8-sig") as file:
            content = file.read()
    except UnicodeDecodeError as err:
        raise InputFileError(
            name, None, f"the file is not UTF-8 text (bad byte at offset {err.start})"
        ) from err
    except OSError as err:
        reason = err.strerror or str(err)
        raise InputFileError(name, None, f"cannot read the log: {reason}") from err
    return parse_log_lines(io.StringIO(content), path=name)


def parse_log_lines(lines: Iterable[str], path: str = "<memory>") -> Log:
    """Validate log lines (1-based numbering; a single ``str`` is split into lines).

    Blank lines and lines starting with ``#`` are skipped. Each record is checked on its
    own first, then the log as a whole, in file order: a pose must be reached by a
    prior or an earlier odometry before it is used, a landmark id keeps one class, and no
    landmark has the reserved id (:func:`reject_reserved_landmark_id`).

    Raises
    ------
    InputFileError
        Naming ``path``, the line and the problem.
    """
    if isinstance(lines, str):
        lines = io.StringIO(lines)
    records = [_parse_line(raw, number, path) for number, raw in _numbered_records(lines)]
    check_complete(len(records), any(isinstance(r, PosePrior) for r in records), path)
    check = OrderCheck(path)
    for record in records:
        check(record)
    log = Log(records=records, path=path)
    reject_reserved_landmark_id(log)
    return log


def check_complete(n_records: int, has_prior: bool, path: str = "<memory>") -> None:
    """Refuse a whole log of ``n_records`` records that has none, or no pose prior.

    Raises
    ------
    InputFileError
        Naming ``path`` (the problem is the file's, so no line).
    """
    if not n_records:
        raise InputFileError(path, None, "the log is empty")
    if not has_prior:
        raise InputFileError(
            path,
            None,
            "no pose has a prior: every position would be relative; "
            'add a {"type": "prior", ...} record',
        )


def parse_log_line(raw: str, number: int, path: str = "<memory>") -> Record | None:
    """The record of one log line (``number``: its 1-based line number), checked on its
    own; None for a blank line or a comment. The rules between records are
    :class:`OrderCheck`'s.

    Examples
    --------
    >>> parse_log_line('{"type": "odometry", "from": 0, "to": 1, "turn": [0.1, 0.2], '
    ...                '"distance": [1.0, 1.1], "time": 12.5}', 7)
    Odometry(source=0, target=1, turn=(0.1, 0.2), distance=(1.0, 1.1), line=7, time=12.5)
    >>> parse_log_line("# a comment", 8) is None
    True

    Raises
    ------
    InputFileError
        Naming ``path``, the line and the problem.
    """
    stripped = raw.strip()
    if not stripped or stripped.startswith("#"):
        return None
    return _parse_line(raw.rstrip(), number, path)


def _numbered_records(lines: Iterable[str]) -> Iterable[tuple[int, str]]:
    for number, raw in enumerate(lines, start=1):
        stripped = raw.strip()
        if stripped and not stripped.startswith("#"):
            yield number, raw.rstrip()


def _reject_constant(token: str) -> Any:
    raise Problem(f"malformed JSON: {token} is not allowed; numbers must be finite")


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    result: dict[str, Any] = {}
    for key, value in pairs:
        if key in result:
            raise Problem(f'field "{key}" appears twice in the record')
        result[key] = value
    return result


def _parse_line(raw: str, number: int, path: str) -> Record:
    value = loads_object(raw)  # a fast decoder's object, when it is the strict one's too
    if value is not None:
        try:
            return record_from_json(value, number)
        except Problem as problem:
            raise InputFileError(path, number, str(problem)) from problem
    try:
        try:
            value = json.loads(raw, parse_constant=_reject_constant, object_pairs_hook=_unique_keys)
        except json.JSONDecodeError as err:
            raise Problem(f"malformed JSON: {err.msg} (column {err.colno})") from err
        except ValueError as err:
            raise Problem(f"malformed JSON: {err}") from err
        except RecursionError as err:
            raise Problem("malformed JSON: nested too deeply") from err
        return record_from_json(value, number)
    except Problem as problem:
        raise InputFileError(path, number, str(problem)) from problem


class OrderCheck:
    """The rules that tie a log's records together, checked one record at a time, in order.

    A pose must be reached (by a prior, or as the target of an earlier odometry or relative
    pose) before it is used, a landmark id keeps one class, one scan sees distinct
    landmarks, no landmark has the reserved id, observation offsets and a ``sensor`` record
    exclude each other, and a log has at most one ``sensor`` record, one ``class`` record
    per class and one ``outliers`` record of each kind. :func:`parse_log_lines` checks a
    whole file with it; an online session (:class:`cuikslam.online.Session`) checks each
    record as it arrives.

    Examples
    --------
    >>> from cuikslam.log.records import Odometry, PosePrior
    >>> check = OrderCheck("trip.jsonl")
    >>> check(PosePrior(0, (0, 0), (0, 0), (0, 0), line=1))
    >>> check(Odometry(3, 4, (0, 0), (1, 1), line=2))
    Traceback (most recent call last):
    ...
    cuikslam.errors.InputFileError: trip.jsonl:2: odometry from pose 3, which no prior ...
    """

    _NO_OFFSETS = (
        "observation offsets cannot be combined with a sensor record: its negative "
        "information is modelled from the robot's pose, not from the sensor's"
    )

    def __init__(self, path: str = "<memory>") -> None:
        self.path = path
        self.reached: set[int] = set()
        """The poses reached so far."""
        self._landmark_seen: dict[str, tuple[str, int]] = {}
        self._scan_seen: dict[tuple[int, object, str], int] = {}
        self._sensor_line: int | None = None
        self._offset_line: int | None = None
        self._class_line: dict[str, int] = {}
        self._outliers_line: dict[bool, int] = {}

    def _fail(self, record: Record, problem: str) -> None:
        raise InputFileError(self.path, record.line, problem)

    def _same_class(self, record: Observation | LandmarkPrior, landmark: str) -> None:
        if landmark == RESERVED_LANDMARK_ID:
            self._fail(record, _RESERVED)
        earlier = self._landmark_seen.setdefault(landmark, (record.landmark_class, record.line))
        if earlier[0] != record.landmark_class:
            self._fail(
                record,
                f'landmark "{landmark}" has class "{record.landmark_class}" here but class '
                f'"{earlier[0]}" on line {earlier[1]}',
            )

    def __call__(self, record: Record) -> None:
        """Check ``record``, the next one of the log, against those before it.

        Raises
        ------
        InputFileError
            Naming the path, the record's line and the rule it breaks.
        """
        match record:
            case PosePrior(pose=pose):
                self.reached.add(pose)
            case Odometry(source=source, target=target):
                if source not in self.reached:
                    self._fail(
                        record,
                        f"odometry from pose {source}, which no prior or earlier odometry reaches",
                    )
                self.reached.add(target)
            case RelativePose(source=source, target=target):
                if source not in self.reached:
                    self._fail(
                        record,
                        f"relative pose from pose {source}, which no prior or earlier odometry "
                        "reaches",
                    )
                self.reached.add(target)
            case Observation(pose=pose, landmark=landmark):
                self._observation(record, pose, landmark)
            case LandmarkPrior(landmark=landmark):
                self._same_class(record, landmark)
            case ClassPrior(landmark_class=cls):
                earlier = self._class_line.setdefault(cls, record.line)
                if earlier != record.line:
                    self._fail(
                        record, f'a second class record for "{cls}"; the first is on line {earlier}'
                    )
            case OutlierBound(window=window):
                earlier = self._outliers_line.setdefault(window is None, record.line)
                if earlier != record.line:
                    scope = "for the whole log" if window is None else "per window"
                    self._fail(
                        record,
                        f"a second outliers record {scope}; the first is on line {earlier} "
                        '(give at most one without "window" and one with it)',
                    )
            case SensorModel():
                if self._sensor_line is not None:
                    self._fail(
                        record, f"a second sensor record; the first is on line {self._sensor_line}"
                    )
                if self._offset_line is not None:
                    self._fail(record, f"{self._NO_OFFSETS} (line {self._offset_line})")
                self._sensor_line = record.line

    def _observation(self, record: Observation, pose: int, landmark: str | None) -> None:
        if record.offset is not None:
            if self._sensor_line is not None:
                self._fail(record, f"{self._NO_OFFSETS} (line {self._sensor_line})")
            self._offset_line = self._offset_line or record.line
        if pose not in self.reached:
            self._fail(
                record,
                f"observation from pose {pose}, which no prior or earlier odometry reaches",
            )
        if landmark is not None:
            self._same_class(record, landmark)
            scan = (pose, record.offset, landmark)  # one sensor pose, one scan
            earlier_line = self._scan_seen.setdefault(scan, record.line)
            if earlier_line != record.line:
                self._fail(
                    record,
                    f'pose {pose} already observed landmark "{landmark}" on line '
                    f"{earlier_line}; observations from one pose form one scan and "
                    "see distinct landmarks",
                )
