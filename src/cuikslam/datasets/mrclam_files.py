"""The files of a UTIAS MRCLAM dataset (1–9 share the format): parsing, checks, time alignment.

A dataset folder holds, as whitespace-separated text with ``#`` header lines and UNIX
times in seconds::

    Barcodes.dat              subject #, barcode #   (subjects 1-5 robots, 6-20 landmarks)
    Landmark_Groundtruth.dat  subject #, x, y, sd x, sd y
    RobotN_Odometry.dat       time, forward velocity [m/s], angular velocity [rad/s]
    RobotN_Measurement.dat    time, barcode #, range [m], bearing [rad]
    RobotN_Groundtruth.dat    time, x [m], y [m], theta [rad]

Every problem is reported as a :class:`~cuikslam.errors.InputFileError` naming the
file and line.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import warnings
from collections import deque
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuikslam.errors import InputFileError

__all__ = [
    "ROBOT_SUBJECTS",
    "MrclamTables",
    "interpolate_poses",
    "keyframe_times",
    "lagged_command_hulls",
    "read_mrclam_tables",
    "read_table",
    "read_table_lines",
    "velocity_steps",
]

ROBOT_SUBJECTS = range(1, 6)
"""Subjects 1-5 are the robots in every MRCLAM dataset."""


def read_table(path: Path, columns: int, *, times: bool = True) -> np.ndarray:
    """The numbers of a MRCLAM text table, one row per data line (``#`` starts a comment).

    See :func:`read_table_lines`, which also gives each row's line number.
    """
    return read_table_lines(path, columns, times=times)[0]


def read_table_lines(
    path: Path, columns: int, *, times: bool = True
) -> tuple[np.ndarray, list[int]]:
    """The numbers of a MRCLAM text table and the line number of each row.

    NumPy parses the table; when it fails a check, a line-by-line pass finds the first
    problem and names its line.

    Parameters
    ----------
    path : Path
        The file.
    columns : int
        Numbers each data line must hold.
    times : bool
        The first column is a time: it must not decrease.

    Raises
    ------
    InputFileError
        Naming file and line: unreadable, a line with the wrong count of numbers, a
        non-finite number, a time going backwards, or no data at all.
    """
    try:
        text = path.read_text(encoding="ascii")
    except FileNotFoundError:
        raise InputFileError(
            path, None, "no such file (is this a MRCLAM dataset folder?)"
        ) from None
    except OSError as err:
        raise InputFileError(path, None, f"cannot read: {err.strerror}") from None
    except UnicodeDecodeError as err:
        raise InputFileError(
            path, None, f"not a text table (bad byte at offset {err.start})"
        ) from None
    fast = _fast_table(text, columns, times)
    if fast is not None:
        return fast
    rows: list[list[float]] = []
    lines: list[int] = []
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        fields = stripped.split()
        if len(fields) != columns:
            raise InputFileError(
                path, number, f"expected {columns} numbers, got {len(fields)}: {stripped[:60]!r}"
            )
        try:
            row = [float(f) for f in fields]
        except ValueError:
            raise InputFileError(path, number, f"not a number in {stripped[:60]!r}") from None
        if not all(math.isfinite(v) for v in row):
            raise InputFileError(path, number, f"a number is not finite in {stripped[:60]!r}")
        if times and rows and row[0] < rows[-1][0]:
            raise InputFileError(
                path, number, f"time {fields[0]} goes back (previous line: {rows[-1][0]!r})"
            )
        rows.append(row)
        lines.append(number)
    if not rows:
        raise InputFileError(path, None, "the table holds no data lines")
    table = np.array(rows, dtype=float)
    table.flags.writeable = False
    return table, lines


def _fast_table(text: str, columns: int, times: bool) -> tuple[np.ndarray, list[int]] | None:
    """The table parsed by NumPy when it passes every check, else None (the line-by-line
    parser then finds the first problem and names its line)."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # NumPy warns on a table without data
            table = np.loadtxt(io.StringIO(text), comments="#", ndmin=2, dtype=float)
    except (ValueError, UserWarning):
        return None
    if table.shape[0] == 0 or table.shape[1] != columns or not np.isfinite(table).all():
        return None
    if times and (np.diff(table[:, 0]) < 0).any():
        return None
    lines = [
        number
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if len(lines) != table.shape[0]:
        return None
    table.flags.writeable = False
    return table, lines


@dataclass(frozen=True)
class MrclamTables:
    """The tables of one robot of a MRCLAM dataset, checked."""

    folder: Path
    robot: int
    odometry: np.ndarray
    """(n, 3) time, commanded forward velocity, commanded angular velocity."""
    measurements: np.ndarray
    """(n, 4) time, barcode, range, bearing."""
    groundtruth: dict[int, np.ndarray | None]
    """Robot subject → (n, 4) time, x, y, theta: this robot's, and the others' once
    :meth:`vicon` has read them (None: no file)."""
    landmarks: dict[int, tuple[float, float]]
    """Landmark subject → true (x, y)."""
    subject_of_barcode: dict[int, int]

    def vicon(self, subject: int) -> np.ndarray | None:
        """Robot ``subject``'s Vicon table, read on first use; None when it has no file."""
        if subject not in self.groundtruth:
            path = self.folder / f"Robot{subject}_Groundtruth.dat"
            self.groundtruth[subject] = read_table(path, 4) if path.is_file() else None
        return self.groundtruth[subject]


def _integer(value: float, path: Path, line: int, what: str) -> int:
    if value != int(value):
        raise InputFileError(path, line, f"{what} {float(value)!r} is not an integer")
    return int(value)


def read_mrclam_tables(folder: str | os.PathLike[str], robot: int) -> MrclamTables:
    """Read and check the tables of robot ``robot`` (1-5) in a MRCLAM dataset folder.

    Raises
    ------
    InputFileError
        If the folder or a file is missing or malformed (naming the file and line).
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputFileError(root, None, "no such folder (expected a MRCLAM dataset folder)")
    if robot not in ROBOT_SUBJECTS:
        raise InputFileError(root, None, f"robot {robot}: MRCLAM robots are 1 to 5")
    barcodes_path = root / "Barcodes.dat"
    barcodes, lines = read_table_lines(barcodes_path, 2, times=False)
    subject_of_barcode: dict[int, int] = {}
    for (subject, code), line in zip(barcodes, lines, strict=True):
        s = _integer(subject, barcodes_path, line, "subject")
        c = _integer(code, barcodes_path, line, "barcode")
        if c in subject_of_barcode:
            raise InputFileError(barcodes_path, line, f"barcode {c} names two subjects")
        subject_of_barcode[c] = s
    landmarks_path = root / "Landmark_Groundtruth.dat"
    table, lines = read_table_lines(landmarks_path, 5, times=False)
    landmarks = {
        _integer(row[0], landmarks_path, line, "subject"): (float(row[1]), float(row[2]))
        for row, line in zip(table, lines, strict=True)
    }
    if robots := sorted(set(landmarks) & set(ROBOT_SUBJECTS)):
        raise InputFileError(landmarks_path, None, f"subjects {robots} are robots, not landmarks")
    groundtruth: dict[int, np.ndarray | None] = {
        robot: read_table(root / f"Robot{robot}_Groundtruth.dat", 4)
    }
    return MrclamTables(
        folder=root,
        robot=robot,
        odometry=read_table(root / f"Robot{robot}_Odometry.dat", 3),
        measurements=read_table(root / f"Robot{robot}_Measurement.dat", 4),
        groundtruth=groundtruth,
        landmarks=landmarks,
        subject_of_barcode=subject_of_barcode,
    )


def keyframe_times(scan_times: np.ndarray, start: float, end: float, gap: float) -> np.ndarray:
    """Pose times: ``start``, every distinct scan time in ``(start, end]``, and enough
    times between them that no two consecutive poses are more than ``gap`` apart.

    >>> keyframe_times(np.array([0.5, 0.5, 3.0]), 0.0, 3.0, 1.0).tolist()
    [0.0, 0.5, 1.3333333333333335, 2.166666666666667, 3.0]
    """
    if not gap > 0:
        raise ValueError(f"the keyframe gap must be positive, got {gap}")
    scans = np.unique(scan_times[(scan_times > start) & (scan_times <= end)])
    anchors = np.concatenate(([start], scans))
    out = [anchors[:1]]
    for a, b in itertools.pairwise(anchors):
        pieces = max(1, math.ceil((b - a) / gap))
        out.append(a + (b - a) * np.arange(1, pieces + 1) / pieces)
        out[-1][-1] = b  # exactly the scan's time
    return np.concatenate(out)


def velocity_steps(odometry: np.ndarray, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
    """The commands that move the robot from time ``t0`` to ``t1``, as steps.

    A command holds from its time stamp until the next one (the last one until ``t1``);
    the steps are the commands clipped to ``[t0, t1]``. ``t0`` must not precede the
    first command.

    Returns
    -------
    rows : numpy.ndarray
        (n,) the row of ``odometry`` each step follows.
    times : numpy.ndarray
        (n + 1,) the step boundaries, from ``t0`` to ``t1`` (no zero-length step).
    """
    t = odometry[:, 0]
    if t0 < t[0]:
        raise ValueError(f"no command before time {t0!r} (the first is at {t[0]!r})")
    first = int(np.searchsorted(t, t0, side="right")) - 1
    last = int(np.searchsorted(t, t1, side="left"))
    bounds = np.concatenate(([t0], t[first + 1 : last], [t1]))
    keep = np.diff(bounds) > 0
    rows = np.arange(first, last)[keep]
    times = np.concatenate((bounds[:-1][keep], [t1]))
    return rows, times


def lagged_command_hulls(odometry: np.ndarray, lag: float) -> np.ndarray:
    """For each command, the hull of the commands in force during the ``lag`` seconds
    before it and while it holds: what the robot may still be doing while it holds.

    Returns an (n, 4) array of forward velocity lo, hi and angular velocity lo, hi. Row
    i is the hull over the commands j <= i whose span reaches past ``t_i - lag`` (a
    command's span lasts until the next time stamp).

    >>> odo = np.array([[0.0, 1.0, 0.0], [1.0, 2.0, 0.5], [1.5, 0.5, -0.5], [3.0, 0.5, -0.5]])
    >>> lagged_command_hulls(odo, 1.0).tolist()[2:]
    [[0.5, 2.0, -0.5, 0.5], [0.5, 0.5, -0.5, -0.5]]
    """
    if not lag >= 0:
        raise ValueError(f"the lag must be >= 0, got {lag}")
    t = odometry[:, 0]
    starts = np.searchsorted(t, t - lag, side="right") - 1
    starts = np.maximum(starts, 0)
    out = np.empty((len(t), 4))
    for column, (lo, hi) in ((1, (0, 1)), (2, (2, 3))):
        values = odometry[:, column]
        out[:, lo] = _sliding(values, starts, np.less_equal)
        out[:, hi] = _sliding(values, starts, np.greater_equal)
    return out


def _sliding(values: np.ndarray, starts: np.ndarray, keeps: np.ufunc) -> np.ndarray:
    """Sliding-window extreme of ``values[starts[i] : i + 1]`` (``starts`` non-decreasing):
    the minimum with ``np.less_equal``, the maximum with ``np.greater_equal``."""
    out = np.empty_like(values)
    window: deque[int] = deque()
    for i, value in enumerate(values.tolist()):
        while window and keeps(value, values[window[-1]]):
            window.pop()
        window.append(i)
        while window[0] < starts[i]:
            window.popleft()
        out[i] = values[window[0]]
    return out


def interpolate_poses(
    groundtruth: np.ndarray, times: np.ndarray, max_gap: float
) -> tuple[np.ndarray, np.ndarray]:
    """Poses at ``times`` interpolated linearly between the Vicon samples around them.

    Headings are unwrapped first, so the interpolated heading is continuous. Returns the
    (n, 3) poses and a mask: False where ``times`` lies outside the recording or between
    two samples more than ``max_gap`` seconds apart (a Vicon gap: no truth there).
    """
    t = groundtruth[:, 0]
    theta = np.unwrap(groundtruth[:, 3])
    poses = np.column_stack(
        [np.interp(times, t, groundtruth[:, 1]), np.interp(times, t, groundtruth[:, 2]),
         np.interp(times, t, theta)]
    )  # fmt: skip
    right = np.clip(np.searchsorted(t, times, side="left"), 1, len(t) - 1)
    gaps = t[right] - t[right - 1]
    exact = t[np.clip(np.searchsorted(t, times), 0, len(t) - 1)] == times
    ok = (times >= t[0]) & (times <= t[-1]) & ((gaps <= max_gap) | exact)
    return poses, ok
