"""TUM trajectory files, as ``evo_traj tum``, ``evo_ape tum`` and ``evo_rpe tum`` read them.

One pose a line, ``timestamp tx ty tz qx qy qz qw``, lines starting with ``#`` are
comments. A cuikslam log has pose ids, not times: the pose id is the timestamp, so a
result and its truth written here share timestamps and evo pairs their poses one to one
(``evo_ape tum truth.txt traj.txt``). The plane is z = 0 and the heading a rotation about z.

Examples
--------
>>> import io, tempfile, os, numpy as np
>>> from cuikslam.interop.estimate import PointEstimate
>>> point = PointEstimate([1, 2], np.array([[0.0, 0.0, 0.0], [1.0, 2.0, np.pi / 2]]), [],
...                       np.zeros((0, 2)), "witness")
>>> path = os.path.join(tempfile.mkdtemp(), "traj.txt")
>>> write_tum_file(point, path)
>>> print(open(path).read().splitlines()[-1])
2 1.0 2.0 0.0 0.0 0.0 0.7071067811865475 0.7071067811865476
>>> stamps, poses_xyt = read_tum_file(path)
>>> stamps.tolist(), np.round(poses_xyt[1], 12).tolist()
([1.0, 2.0], [1.0, 2.0, 1.570796326795])
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np

from cuikslam._atomic import atomic_write_text
from cuikslam.errors import InputFileError
from cuikslam.interop.estimate import PointEstimate

__all__ = ["heading_quaternion", "read_tum_file", "tum_lines", "write_tum_file"]


def heading_quaternion(theta: float) -> tuple[float, float, float, float]:
    """``(qx, qy, qz, qw)`` of a rotation by ``theta`` about the z axis.

    Examples
    --------
    >>> [round(q, 12) for q in heading_quaternion(math.pi)]
    [0.0, 0.0, 1.0, 0.0]
    """
    return 0.0, 0.0, math.sin(theta / 2), math.cos(theta / 2)


def tum_lines(point: PointEstimate, comments: Sequence[str] = ()) -> list[str]:
    """The lines of the TUM file of ``point``'s poses, by increasing pose id, after a header
    of ``#`` comments (the point's source, the columns, then ``comments``)."""
    header = [
        f"# cuikslam trajectory: {point.source}",
        "# timestamp tx ty tz qx qy qz qw (timestamp = pose id; z = 0; heading about z)",
        *(f"# {c}" for c in comments),
    ]
    rows = []
    for pose_id, (x, y, theta) in sorted(
        zip(point.pose_ids, point.poses_xyt.tolist(), strict=True)
    ):
        qx, qy, qz, qw = heading_quaternion(theta)
        rows.append(f"{pose_id} {x!r} {y!r} 0.0 {qx!r} {qy!r} {qz!r} {qw!r}")
    return header + rows


def write_tum_file(
    point: PointEstimate, path: str | os.PathLike[str], comments: Sequence[str] = ()
) -> None:
    """Write ``point``'s poses as a TUM trajectory to ``path`` (atomically; see
    :func:`tum_lines`)."""
    atomic_write_text(path, "\n".join(tum_lines(point, comments)) + "\n")


def read_tum_file(path: str | os.PathLike[str]) -> tuple[np.ndarray, np.ndarray]:
    """Read a TUM trajectory of a planar motion.

    Returns
    -------
    timestamps : ndarray, shape (n,)
    poses_xyt : ndarray, shape (n, 3)
        ``x, y`` and the heading ``2 atan2(qz, qw)`` in (-2π, 2π]; ``tz``, ``qx``, ``qy``
        are read and not checked.

    Raises
    ------
    InputFileError
        Naming the file and line when it cannot be read or a line is not eight numbers.
    """
    try:
        with open(path, encoding="utf-8") as handle:
            text = handle.read()
    except (OSError, UnicodeDecodeError) as err:
        raise InputFileError(path, None, f"cannot read TUM file: {err}") from None
    stamps, poses = [], []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = line.split()
        try:
            values = [float(f) for f in fields]
        except ValueError:
            values = []
        if len(values) != 8 or not all(map(math.isfinite, values)):
            raise InputFileError(
                path, number, "expected 'timestamp tx ty tz qx qy qz qw' (eight finite numbers)"
            )
        stamps.append(values[0])
        poses.append([values[1], values[2], 2 * math.atan2(values[6], values[7])])
    return np.array(stamps, dtype=float), np.array(poses, dtype=float).reshape(-1, 3)
