"""The three files of the Victoria Park data set (University of Sydney, ACFR): parsing and checks.

Whitespace-separated text without a header, times in seconds::

    inputs.dat        time, rear-left wheel speed [m/s] (encoder), steering angle [rad]
    measurements.dat  time, range [m], bearing [rad], trunk diameter [m]  (one line per trunk
                      detected in one laser scan; one scan's lines share their time)
    gps.dat           time, x [m], y [m]  (GPS in a local frame; gaps under tree cover)

Every problem is reported as a :class:`~cuikslam.errors.InputFileError` naming the file
and, when it is about one line, the line.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuikslam.datasets.mrclam_files import read_table_lines
from cuikslam.errors import InputFileError

__all__ = ["FILES", "VictoriaParkTables", "read_victoria_park_tables"]

FILES = {
    "inputs": ("inputs.dat", 3),
    "measurements": ("measurements.dat", 4),
    "gps": ("gps.dat", 3),
}
"""Each table: its file name and its number of columns."""


@dataclass(frozen=True)
class VictoriaParkTables:
    """The tables of a Victoria Park folder, checked (times never go back)."""

    folder: Path
    inputs: np.ndarray
    """(n, 3) time, rear-left wheel speed, steering angle."""
    measurements: np.ndarray
    """(m, 4) time, range, bearing (laser frame, 0..pi), trunk diameter."""
    gps: np.ndarray
    """(g, 3) time, x, y."""
    measurement_lines: list[int]
    """The line of each row of ``measurements`` in its file (for messages)."""


def _read(folder: Path, name: str) -> tuple[np.ndarray, list[int]]:
    filename, columns = FILES[name]
    path = folder / filename
    if not path.is_file():
        raise InputFileError(
            path,
            None,
            "no such file (is this a Victoria Park folder? it needs inputs.dat, "
            "measurements.dat and gps.dat)",
        )
    return read_table_lines(path, columns)


def read_victoria_park_tables(folder: str | os.PathLike[str]) -> VictoriaParkTables:
    """Read and check the three tables of a Victoria Park folder.

    Parameters
    ----------
    folder : str or PathLike
        The folder holding ``inputs.dat``, ``measurements.dat`` and ``gps.dat``.

    Returns
    -------
    VictoriaParkTables

    Raises
    ------
    InputFileError
        Naming file and line: a missing or unreadable file, a line without the file's
        number of columns, a number that is not finite, a time going back, a negative
        range or diameter, a bearing outside [0, pi] (with a little slack), or a steering
        angle beyond +-pi/2 (the car model divides by its cosine).
    """
    root = Path(folder)
    inputs, input_lines = _read(root, "inputs")
    measurements, lines = _read(root, "measurements")
    gps, _ = _read(root, "gps")
    steer = np.flatnonzero(np.abs(inputs[:, 2]) >= 1.5)
    if steer.size:
        k = int(steer[0])
        raise InputFileError(
            root / FILES["inputs"][0],
            input_lines[k],
            f"steering angle {inputs[k, 2]!r} rad is beyond +-1.5 rad: not a car's steering",
        )
    checks = (
        (measurements[:, 1] < 0, "a range cannot be negative"),
        (measurements[:, 3] < 0, "a trunk diameter cannot be negative"),
        (
            (measurements[:, 2] < -0.01) | (measurements[:, 2] > math.pi + 0.01),
            "the laser's bearings run over 0..pi",
        ),
    )
    for bad, why in checks:
        rows = np.flatnonzero(bad)
        if rows.size:
            k = int(rows[0])
            raise InputFileError(
                root / FILES["measurements"][0],
                lines[k],
                f"{why}: {' '.join(repr(float(v)) for v in measurements[k])}",
            )
    return VictoriaParkTables(root, inputs, measurements, gps, lines)
