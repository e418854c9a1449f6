"""Bounds of the Victoria Park importer measured against GPS.

GPS is the only reference of the data set, with errors of decimetres in the open and
metres under the trees, and it sees neither the heading nor the trunks. So:

* **Motion** is calibrated as ``cuikslam calibrate mrclam`` scales the motion bounds: the
  part is cut into windows of ``window`` seconds; each window is imported on its own (its
  first pose anchored on GPS as the importer does, its heading ``± window_heading`` around
  the one fitted to the GPS track) and its poses reached by the motion alone (no
  observation); a window *holds* when every GPS fix at its poses lies in the pose's box
  mapped to the antenna and grown by ``gps_check`` metres. The margins of :data:`BASE`
  (speed scale and offset, steering) are scaled together, by bisection, to the smallest
  factor under which the share ``quantile`` of the windows hold. The first pose's heading
  bound is kept from ``base`` (stated: GPS fixes a heading only as well as its track).
* **The nominal model** (speed scale, steering offset, GPS antenna in the car frame) is
  fitted by least squares to the GPS tracks of the windows and reported, not used: the
  bounds are symmetric around the readings, so they must cover the offsets found.
* **Range and bearing** cannot be calibrated (no tree has a known position): their bounds
  are stated (:class:`~.victoria_park.VictoriaParkBounds`) and kept.
"""

from __future__ import annotations

import itertools
import math
import os
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cuikslam.datasets.victoria_park import (
    LASER_A,
    LASER_B,
    VictoriaParkBounds,
    gps_inside,
    nominal_path,
    read_victoria_park,
)
from cuikslam.datasets.victoria_park_files import VictoriaParkTables, read_victoria_park_tables
from cuikslam.errors import InputFileError
from cuikslam.motion import compose_relative

__all__ = [
    "BASE",
    "VictoriaParkCalibration",
    "calibrate_victoria_park",
    "check_victoria_park",
    "scan_consistency",
    "window_starts",
]

BASE = VictoriaParkBounds(speed_scale_min=0.99, speed_scale_max=1.01, speed=0.02, steering=0.002)
"""The margins scaled together: factor f gives scale ``1 ± 0.01 f``, speed ``± 0.02 f``,
steering ``± 0.002 f``."""


@dataclass
class VictoriaParkCalibration:
    """Bounds measured on a part of the run, what they come from, and the part checked."""

    bounds: VictoriaParkBounds
    calibrated_on: dict[str, Any]
    errors: dict[str, Any]


def _scaled(bounds: VictoriaParkBounds, factor: float) -> VictoriaParkBounds:
    return replace(
        bounds,
        speed_scale_min=max(1 - (1 - BASE.speed_scale_min) * factor, 0.0),
        speed_scale_max=1 + (BASE.speed_scale_max - 1) * factor,
        speed=BASE.speed * factor,
        steering=BASE.steering * factor,
    )


def window_starts(start: float, end: float, window: float) -> list[float]:
    """The starts of the windows of ``window`` seconds that cut ``start .. end``."""
    return [float(t) for t in np.arange(start, end - window / 2, window)]


def scan_consistency(
    tables: VictoriaParkTables, start: float, end: float, gate: float = 1.0
) -> dict[str, float]:
    """How much one trunk's readings differ between consecutive scans (about 0.21 s apart).

    Each trunk of a scan is carried to the next scan by the nominal motion and paired with
    the nearest trunk there (within ``gate`` metres, up to 30 m away); the differences of
    range and bearing between the pair are twice an error bound at most, plus the motion's
    error over 0.2 s. A check of the stated bounds, not a calibration against a truth.
    """
    inp, meas = tables.inputs, tables.measurements
    meas = meas[(meas[:, 0] >= start) & (meas[:, 0] <= end)]
    path = nominal_path(inp[:, 0], inp[:, 1], inp[:, 2])
    scans = np.unique(meas[:, 0])

    def laser_and_trees(t: float):
        x, y, th = (float(np.interp(t, inp[:, 0], path[:, k])) for k in range(3))
        lx = x + LASER_A * math.cos(th) - LASER_B * math.sin(th)
        ly = y + LASER_A * math.sin(th) + LASER_B * math.cos(th)
        z = meas[meas[:, 0] == t]
        b = th + z[:, 2] - math.pi / 2
        trees = np.stack([lx + z[:, 1] * np.cos(b), ly + z[:, 1] * np.sin(b)], -1)
        return (lx, ly, th), trees, z

    d_range, d_bearing = [], []
    for a, b in itertools.pairwise(scans):
        if b - a > 0.3:
            continue
        _, trees_a, za = laser_and_trees(float(a))
        (lx, ly, th), trees_b, zb = laser_and_trees(float(b))
        for q, reading in zip(trees_a, za, strict=True):
            dist = np.hypot(*(trees_b - q).T)
            j = int(np.argmin(dist))
            if dist[j] < gate and reading[1] < 30:
                d_range.append(zb[j, 1] - math.hypot(q[0] - lx, q[1] - ly))
                predicted = math.atan2(q[1] - ly, q[0] - lx) - th + math.pi / 2
                d_bearing.append((zb[j, 2] - predicted + math.pi) % (2 * math.pi) - math.pi)
    if not d_range:
        return {"pairs": 0}
    r, b = np.abs(d_range), np.abs(d_bearing)
    return {
        "pairs": int(r.size),
        "range_median": float(np.median(r)),
        "range_p99": float(np.quantile(r, 0.99)),
        "range_max": float(r.max()),
        "bearing_median": float(np.median(b)),
        "bearing_p99": float(np.quantile(b, 0.99)),
        "bearing_max": float(b.max()),
    }


def check_victoria_park(
    tables: VictoriaParkTables,
    bounds: VictoriaParkBounds,
    starts: list[float],
    *,
    window: float,
    keyframe: float,
    gps_check: float,
) -> dict[str, Any]:
    """Import each window from motion alone and compare its pose boxes with GPS.

    Returns
    -------
    dict
        ``windows`` checked, ``held`` (every fix inside), ``fixes``, ``inside``, and
        ``worst`` (the largest distance of a fix from its grown box, metres).
    """
    held = windows = fixes = inside = 0
    worst = 0.0
    for t0 in starts:
        try:
            log, ref = read_victoria_park(
                tables, start=t0, duration=window, keyframe=keyframe, bounds=bounds
            )
        except InputFileError:
            continue  # no GPS fix to anchor this window
        if ref.xy.shape[0] < 2:
            continue
        prior = log.priors[0]
        boxes = {0: (prior.x, prior.y, prior.theta)}
        for move in log.relative_poses:
            boxes[move.target] = compose_relative(
                [boxes[move.source], (move.dx, move.dy, move.dtheta)]
            )
        n_in, n, misses = gps_inside(boxes, ref, gps_check)
        windows += 1
        fixes += n
        inside += n_in
        held += not misses
        worst = max([worst, *(d for _, d in misses)])
    return {"windows": windows, "held": held, "fixes": fixes, "inside": inside, "worst": worst}


def _nominal_fit(tables: VictoriaParkTables, starts: list[float], window: float) -> dict:
    """Least-squares speed scale, steering offset and antenna position on the windows."""
    from scipy.optimize import least_squares

    inp, gps = tables.inputs, tables.gps
    parts = []
    for t0 in starts:
        g = gps[(gps[:, 0] >= t0) & (gps[:, 0] <= t0 + window)]
        s = (inp[:, 0] >= t0) & (inp[:, 0] <= t0 + window)
        if len(g) >= 10 and s.sum() >= 2 and np.hypot(*(g[-1, 1:] - g[0, 1:])) >= 10:
            parts.append((g, s))
    if not parts:
        return {}

    def residuals(p: np.ndarray) -> np.ndarray:
        scale, offset, ax, ay = p[:4]
        out = []
        for j, (g, s) in enumerate(parts):
            th0, x0, y0 = p[4 + 3 * j : 7 + 3 * j]
            path = nominal_path(inp[s, 0], inp[s, 1], inp[s, 2] + offset, scale)
            t = inp[s, 0]
            px, py, pt = (np.interp(g[:, 0], t, path[:, k]) for k in range(3))
            lx = px + ax * np.cos(pt) - ay * np.sin(pt)
            ly = py + ax * np.sin(pt) + ay * np.cos(pt)
            c, si = math.cos(th0), math.sin(th0)
            out += [c * lx - si * ly + x0 - g[:, 1], si * lx + c * ly + y0 - g[:, 2]]
        return np.concatenate(out)

    p0 = [1.0, 0.0, LASER_A, LASER_B]
    for g, _ in parts:
        chord = g[min(10, len(g) - 1), 1:] - g[0, 1:]
        th0 = math.atan2(chord[1], chord[0])
        c, si = math.cos(th0), math.sin(th0)
        p0 += [th0, g[0, 1] - c * LASER_A + si * LASER_B, g[0, 2] - si * LASER_A - c * LASER_B]
    fit = least_squares(residuals, p0, loss="soft_l1", f_scale=0.5, diff_step=1e-4)
    distances, at = [], 0
    for g, _ in parts:
        n = len(g)
        distances.append(np.hypot(fit.fun[at : at + n], fit.fun[at + n : at + 2 * n]))
        at += 2 * n
    d = np.concatenate(distances)
    return {
        "windows": len(parts),
        "speed_scale": float(fit.x[0]),
        "steering_offset": float(fit.x[1]),
        "antenna": [float(fit.x[2]), float(fit.x[3])],
        "gps_residual_median": float(np.median(d)),
        "gps_residual_p90": float(np.quantile(d, 0.9)),
    }


def calibrate_victoria_park(
    folder: str | os.PathLike[str] | VictoriaParkTables,
    *,
    start: float = 0.0,
    duration: float = 300.0,
    window: float = 20.0,
    keyframe: float = 1.0,
    quantile: float = 1.0,
    gps_check: float = 2.5,
    window_heading: float = 0.1,
    base: VictoriaParkBounds | None = None,
) -> VictoriaParkCalibration:
    """Measure the motion bounds on ``start .. start + duration``.

    Parameters
    ----------
    window : float
        Length of each window [s] whose motion is checked against GPS.
    quantile : float
        Share (0 < q <= 1) of the windows that must hold.
    gps_check : float
        GPS error [m] allowed in the check (a fix is inside when within this of its box).
    window_heading : float
        Margin [rad] of each window's first heading around the one fitted to GPS.
    base : VictoriaParkBounds, optional
        The bounds kept as they are (range, bearing, GPS at the prior).

    Raises
    ------
    InputFileError
        If a file is malformed or no window of the part can be checked.
    ValueError
        If ``quantile`` is not in (0, 1].
    """
    if not 0 < quantile <= 1:
        raise ValueError(f"the quantile must be in (0, 1], got {quantile}")
    tables = folder if isinstance(folder, VictoriaParkTables) else read_victoria_park_tables(folder)
    base = base or VictoriaParkBounds()
    end = start + duration
    starts = window_starts(start, end, window)

    def holds(factor: float) -> tuple[bool, dict]:
        trial = replace(_scaled(base, factor), heading=window_heading)
        found = check_victoria_park(
            tables, trial, starts, window=window, keyframe=keyframe, gps_check=gps_check
        )
        need = math.ceil(quantile * found["windows"] - 1e-9)
        return found["held"] >= need, found

    ok, found = holds(1.0)
    if found["windows"] == 0:
        raise InputFileError(tables.folder, None, f"no window of {start}..{end} s has GPS")
    lo, hi = 0.0, 1.0
    while not ok and hi < 256:
        lo, hi = hi, 2 * hi
        ok, found = holds(hi)
    for _ in range(7):
        mid = (lo + hi) / 2
        ok_mid, _ = holds(mid)
        lo, hi = (lo, mid) if ok_mid else (mid, hi)
    bounds = _scaled(base, hi)
    bounds = replace(
        bounds,
        speed_scale_min=math.floor(bounds.speed_scale_min * 1e4) / 1e4,
        speed_scale_max=math.ceil(bounds.speed_scale_max * 1e4) / 1e4,
        speed=math.ceil(bounds.speed * 1e4) / 1e4,
        steering=math.ceil(bounds.steering * 1e5) / 1e5,
    )
    _, found = holds_bounds(
        tables, replace(bounds, heading=window_heading), starts, window, keyframe, gps_check
    )
    return VictoriaParkCalibration(
        bounds=bounds,
        calibrated_on={
            "folder": os.fspath(tables.folder),
            "start": start,
            "duration": duration,
            "window": window,
            "keyframe": keyframe,
            "quantile": quantile,
            "gps_check": gps_check,
            "window_heading": window_heading,
        },
        errors={"factor_of_base_margins": hi, "windows": found, "nominal_fit": _nominal_fit(
            tables, starts, window)},
    )  # fmt: skip


def holds_bounds(
    tables: VictoriaParkTables,
    bounds: VictoriaParkBounds,
    starts: list[float],
    window: float,
    keyframe: float,
    gps_check: float,
) -> tuple[bool, dict]:
    """Whether every window holds under ``bounds``, and the counts."""
    found = check_victoria_park(
        tables, bounds, starts, window=window, keyframe=keyframe, gps_check=gps_check
    )
    return found["held"] == found["windows"], found
