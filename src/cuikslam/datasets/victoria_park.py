"""Importer for the Victoria Park data set (ACFR, Guivant and Nebot): a car among trees.

A utility car drives through a park; a laser ahead of its rear axle detects tree trunks
(all alike: unknown correspondence); GPS, where the trees let it, gives a rough reference.
:func:`read_victoria_park` turns a time window into a :class:`~cuikslam.log.records.Log`
and a :class:`GpsReference` (GPS at the poses' times: a reference with errors of up to
metres, **not** a truth, and of the antenna, not of the pose).

Vehicle geometry (published vehicle parameters of the data set: Guivant and Nebot's
description of the ACFR utility car used in the Victoria Park experiments): wheelbase
``L`` = 2.83 m; the laser sits ``a`` = 3.78 m ahead of the rear axle and ``b`` = 0.50 m to
the left of the centre line; the speed encoder is on the rear-left wheel, ``H`` = 0.76 m
from the centre line. The GPS antenna is taken at the laser (a fit of the odometry to GPS
puts it at (3.78, 0.65-0.83) m: within the GPS error of the laser).

Modelling (each interval holds the truth whenever the bounds of :class:`VictoriaParkBounds`
do):

* **Poses.** A pose is the centre of the rear axle, heading along the car. The first pose
  is at the window's first GPS fix; then one pose at the first scan with detections at
  least ``keyframe`` seconds after the previous pose, or ``keyframe`` seconds after it
  when no scan comes within two keyframes.
* **Motion** (Ackermann kinematics, no wheel slip; :func:`car_motion`). Between two input
  samples the true wheel speed lies in the hull of the two readings, times a scale in
  ``[speed_scale_min, speed_scale_max]``, ``± speed``; the true steering angle in the hull
  of the two readings ``± steering`` (an offset of the steering sensor included). The rear
  axle's centre then drives along the heading at ``v_c = v_wheel / (1 - H tan(phi) / L)``
  (the left wheel turns on a circle ``H`` smaller) and turns at ``v_c tan(phi) / L``; both
  are enclosed in intervals with outward rounding (``tan`` is increasing on the steering
  range) and composed by :func:`cuikslam.motion.compose_steps`, which is sound for speeds
  and turn rates that stay in their intervals at every instant of each step.
* **Observations.** Class ``"tree"``, no landmark id. The laser's bearing runs over 0..pi
  from the car's right to its left, so the bearing from the laser's heading is the reading
  minus pi/2, ``± bearing``. The data set does not say whether a range reaches the trunk's
  surface or its centre, so the interval holds both: ``[r - range, r + diameter / 2 +
  range]``. Each observation's sensor pose is the mount ``(a, b, 0)`` composed, for a scan
  between keyframes (``every_scan``), after the motion since the keyframe.
* **Prior.** The first pose gets the box of the rear axle whose laser lies within ``± gps``
  of the first GPS fix, with the heading ``± heading`` around the heading that best turns
  the nominal odometry of the next ``HEADING_WINDOW`` seconds onto the GPS track. No
  sensor record: the detector misses trunks, so an unseen tree says nothing.
"""

from __future__ import annotations

import math
import os
import warnings
from dataclasses import dataclass, fields

import numpy as np

from cuikslam.datasets.victoria_park_files import VictoriaParkTables, read_victoria_park_tables
from cuikslam.errors import InputFileError
from cuikslam.log.records import Bounds, Log, Observation, PosePrior, Record, RelativePose
from cuikslam.motion import RelativeBounds, compose_relative, compose_steps

__all__ = [
    "LASER_A",
    "LASER_B",
    "WHEELBASE",
    "WHEEL_OFFSET",
    "GpsReference",
    "VictoriaParkBounds",
    "car_motion",
    "gps_inside",
    "nominal_path",
    "read_victoria_park",
]

WHEELBASE = 2.83
"""``L`` [m]: rear axle to front axle (published vehicle parameters)."""
LASER_A = 3.78
"""``a`` [m]: the laser ahead of the rear axle (published vehicle parameters)."""
LASER_B = 0.50
"""``b`` [m]: the laser left of the centre line (published vehicle parameters)."""
WHEEL_OFFSET = 0.76
"""``H`` [m]: the encoder's rear-left wheel from the centre line (published parameters)."""
MOUNT: RelativeBounds = ((LASER_A, LASER_A), (LASER_B, LASER_B), (0.0, 0.0))
HEADING_WINDOW = 30.0
"""Seconds of GPS after the first pose that fix its heading."""
HEADING_MIN_CHORD = 5.0
"""GPS fixes nearer than this [m] to the first one do not count for the heading."""
GPS_GAP = 0.5
"""GPS is interpolated at a time only between two fixes at most this far apart [s]."""


@dataclass(frozen=True)
class VictoriaParkBounds:
    """Error bounds of the Victoria Park importer (all >= 0; see the module docstring).

    The motion defaults are those ``cuikslam calibrate victoria-park`` measured on the
    first 5 minutes against GPS with a GPS error of 2.5 m (``docs/real-data.md``), rounded
    outward; the first heading's bound is stated (the car starts in the open). GPS cannot
    calibrate the range and bearing bounds (no trunk has a known position): they are
    stated, and checked only by the consistency of one trunk seen in consecutive scans
    (:func:`.victoria_park_calibrate.scan_consistency`).
    """

    speed_scale_min: float = 0.976
    speed_scale_max: float = 1.024
    speed: float = 0.047
    """[m/s] added to the scaled wheel speed's hull."""
    steering: float = 0.0047
    """[rad] around the steering readings' hull (a sensor offset included)."""
    range: float = 0.3
    """[m] around the range (stated, not calibrated: GPS cannot see the trunks)."""
    bearing: float = 0.025
    """[rad] around the bearing (stated, not calibrated)."""
    gps: float = 1.0
    """[m] GPS error at the first pose (the prior)."""
    heading: float = 0.05
    """[rad] around the first pose's heading fitted to GPS (the prior)."""

    @classmethod
    def from_dict(
        cls, values: dict[str, float], path: str | os.PathLike[str]
    ) -> VictoriaParkBounds:
        """The bounds of a bounds file's ``"bounds"`` object (missing ones keep defaults)."""
        bounds = cls(**values)
        if bounds.speed_scale_min > bounds.speed_scale_max:
            raise InputFileError(path, None, "speed_scale_min is above speed_scale_max")
        return bounds

    @classmethod
    def names(cls) -> list[str]:
        """The bounds' names (the keys of a bounds file)."""
        return [f.name for f in fields(cls)]


@dataclass(frozen=True)
class GpsReference:
    """GPS at the poses' times, where it has fixes on both sides within ``GPS_GAP``.

    ``xy[i]`` is the antenna (taken at the laser, pose ``⊕ (a, b)``) at pose
    ``pose_ids[i]``, a reference with metres of error under tree cover, not a truth.
    """

    pose_ids: list[int]
    times: list[float]
    xy: np.ndarray

    def to_json(self) -> dict:
        """The reference as the JSON object of ``NAME.gps.json``."""
        return {
            "cuikslam_gps_reference": 1,
            "note": "GPS of the antenna (taken at the laser, pose + (a, b)) at each pose's "
            "time; errors of up to metres under tree cover: a reference, not a truth",
            "antenna": [LASER_A, LASER_B],
            "poses": {
                str(p): {"time": t, "x": float(x), "y": float(y)}
                for p, t, (x, y) in zip(self.pose_ids, self.times, self.xy.tolist(), strict=True)
            },
        }


def _outward(lo: np.ndarray, hi: np.ndarray, ulps: int = 2) -> tuple[np.ndarray, np.ndarray]:
    for _ in range(ulps):
        lo, hi = np.nextafter(lo, -np.inf), np.nextafter(hi, np.inf)
    return lo, hi


def _mul(alo, ahi, blo, bhi) -> tuple[np.ndarray, np.ndarray]:
    p = np.stack([alo * blo, alo * bhi, ahi * blo, ahi * bhi])
    return _outward(p.min(axis=0), p.max(axis=0), 1)


def car_motion(
    t: np.ndarray, speed: np.ndarray, steering: np.ndarray, ta: float, tb: float,
    bounds: VictoriaParkBounds,
) -> RelativeBounds:  # fmt: skip
    """Enclose the rear axle's motion from time ``ta`` to ``tb`` (see the module docstring).

    Parameters
    ----------
    t, speed, steering : np.ndarray
        The input samples: times (increasing), wheel speeds, steering angles.
    ta, tb : float
        The interval, ``t[0] <= ta <= tb <= t[-1]``.
    bounds : VictoriaParkBounds

    Returns
    -------
    ((float, float), (float, float), (float, float))
        ``(dx, dy, dtheta)`` of the pose at ``tb`` in the frame of the pose at ``ta``.
    """
    if tb <= ta:
        return ((0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    inner = t[(t > ta) & (t < tb)]
    tau = np.concatenate([[ta], inner, [tb]])
    k0 = np.clip(np.searchsorted(t, tau[:-1], side="right") - 1, 0, t.size - 1)
    k1 = np.clip(np.searchsorted(t, tau[1:], side="left"), 0, t.size - 1)
    vlo, vhi = np.minimum(speed[k0], speed[k1]), np.maximum(speed[k0], speed[k1])
    vlo, vhi = _mul(vlo, vhi, bounds.speed_scale_min, bounds.speed_scale_max)
    vlo, vhi = _outward(vlo - bounds.speed, vhi + bounds.speed)
    plo = np.minimum(steering[k0], steering[k1]) - bounds.steering
    phi = np.maximum(steering[k0], steering[k1]) + bounds.steering
    tlo, thi = _outward(np.tan(plo), np.tan(phi), 4)
    klo, khi = _outward(1.0 - WHEEL_OFFSET / WHEELBASE * thi, 1.0 - WHEEL_OFFSET / WHEELBASE * tlo)
    if np.any(klo <= 0):
        raise ValueError("steering beyond the model's range (the inner wheel would stop)")
    q = np.stack([vlo / klo, vlo / khi, vhi / klo, vhi / khi])
    clo, chi = _outward(q.min(axis=0), q.max(axis=0), 1)
    wlo, whi = _mul(clo, chi, tlo, thi)
    wlo, whi = _outward(wlo / WHEELBASE, whi / WHEELBASE, 1)
    return compose_steps(np.stack([clo, chi], -1), np.stack([wlo, whi], -1), tau)


def nominal_path(
    t: np.ndarray, speed: np.ndarray, steering: np.ndarray, scale: float = 1.0
) -> np.ndarray:
    """Dead reckoning of the rear axle at face value from ``(0, 0, 0)`` at ``t[0]``: (n, 3)."""
    k = 1.0 - WHEEL_OFFSET / WHEELBASE * np.tan(steering)
    vc = scale * speed / k
    w = vc * np.tan(steering) / WHEELBASE
    dt = np.diff(t)
    th = np.concatenate([[0.0], np.cumsum(w[:-1] * dt)])
    x = np.concatenate([[0.0], np.cumsum(vc[:-1] * np.cos(th[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(vc[:-1] * np.sin(th[:-1]) * dt)])
    return np.stack([x, y, th], axis=-1)


def gps_at(gps: np.ndarray, times: np.ndarray) -> np.ndarray:
    """GPS interpolated at ``times`` ((n, 2); NaN where no two fixes within ``GPS_GAP``
    bracket the time)."""
    g_t = gps[:, 0]
    j = np.clip(np.searchsorted(g_t, times, side="right"), 1, g_t.size - 1)
    ok = (g_t[j - 1] <= times) & (times <= g_t[j]) & (g_t[j] - g_t[j - 1] <= GPS_GAP)
    exact = np.isin(times, g_t)
    out = np.stack([np.interp(times, g_t, gps[:, 1]), np.interp(times, g_t, gps[:, 2])], -1)
    out[~(ok | exact)] = np.nan
    return out


def _first_heading(tables: VictoriaParkTables, t0: float, scale: float) -> float | None:
    """The heading that turns the nominal laser path of the next ``HEADING_WINDOW`` seconds
    best onto the GPS track from ``t0`` (None if the car does not move far enough)."""
    inp = tables.inputs
    s = (inp[:, 0] >= t0) & (inp[:, 0] <= t0 + HEADING_WINDOW)
    if s.sum() < 2:
        return None
    path = nominal_path(inp[s, 0], inp[s, 1], inp[s, 2], scale)
    c, si = np.cos(path[:, 2]), np.sin(path[:, 2])
    laser = path[:, :2] + np.stack([LASER_A * c - LASER_B * si, LASER_A * si + LASER_B * c], -1)
    laser -= laser[0]
    g = tables.gps[(tables.gps[:, 0] >= t0) & (tables.gps[:, 0] <= inp[s, 0][-1])]
    g0 = gps_at(tables.gps, np.array([t0]))[0]
    q = np.stack(
        [np.interp(g[:, 0], inp[s, 0], laser[:, 0]), np.interp(g[:, 0], inp[s, 0], laser[:, 1])], -1
    )
    d = g[:, 1:] - g0
    far = np.hypot(*q.T) >= HEADING_MIN_CHORD
    if not far.any():
        return None
    q, d = q[far], d[far]
    return math.atan2(float(np.sum(q[:, 0] * d[:, 1] - q[:, 1] * d[:, 0])), float(np.sum(q * d)))


def _keyframes(scan_times: np.ndarray, t0: float, end: float, keyframe: float) -> list[float]:
    """The poses' times: ``t0``, then the first scan ``keyframe`` after the last pose (or
    ``keyframe`` after it when no scan comes within two keyframes), up to ``end``."""
    keys = [t0]
    while True:
        j = int(np.searchsorted(scan_times, keys[-1] + keyframe, side="left"))
        nxt = float(scan_times[j]) if j < scan_times.size else math.inf
        if nxt > keys[-1] + 2 * keyframe:
            nxt = keys[-1] + keyframe
        if nxt > end:
            return keys
        keys.append(nxt)


def read_victoria_park(
    folder: str | os.PathLike[str] | VictoriaParkTables,
    *,
    start: float = 0.0,
    duration: float | None = None,
    keyframe: float = 1.0,
    bounds: VictoriaParkBounds | None = None,
    max_range: float | None = None,
    every_scan: bool = False,
) -> tuple[Log, GpsReference]:
    """Import the window ``start .. start + duration`` [s, data time] of a Victoria Park folder.

    Parameters
    ----------
    folder : str, PathLike or VictoriaParkTables
        The folder (or its tables, read by :func:`read_victoria_park_tables`).
    start, duration : float
        The window [s]; the first pose is at the first GPS fix at or after ``start`` (and
        after the first input sample). Default: the whole run.
    keyframe : float
        Seconds between poses (at least).
    bounds : VictoriaParkBounds, optional
        Error bounds (default :class:`VictoriaParkBounds()`).
    max_range : float, optional
        Keep only the detections nearer than this [m] (far trunks add branches to the
        search and little else). Dropping readings never breaks the guarantee.
    every_scan : bool
        Also keep the scans between keyframes, each from its sensor pose (the motion since
        the keyframe, then the mount); by default only the keyframes' scans.

    Returns
    -------
    (Log, GpsReference)

    Raises
    ------
    InputFileError
        If a file is malformed (file and line named), or the window holds no GPS fix to
        anchor the first pose, or no input samples.
    """
    tables = folder if isinstance(folder, VictoriaParkTables) else read_victoria_park_tables(folder)
    bounds = bounds or VictoriaParkBounds()
    if keyframe <= 0:
        raise ValueError(f"keyframe must be > 0 s, got {keyframe}")
    inp = tables.inputs
    t_in = inp[:, 0]
    end = t_in[-1] if duration is None else min(start + duration, t_in[-1])
    fixes = tables.gps[:, 0]
    fixes = fixes[(fixes >= max(start, t_in[0])) & (fixes < end)]
    if fixes.size == 0 or inp.shape[0] < 2:
        raise InputFileError(
            tables.folder, None, f"no GPS fix and input samples in {start:g}..{end:g} s to "
            "anchor the first pose",
        )  # fmt: skip
    t0 = float(fixes[0])
    g0 = tables.gps[np.searchsorted(tables.gps[:, 0], t0), 1:]
    scale = (bounds.speed_scale_min + bounds.speed_scale_max) / 2
    heading = _first_heading(tables, t0, scale)
    if heading is None:
        warnings.warn(
            f"the car does not move {HEADING_MIN_CHORD} m within {HEADING_WINDOW} s of "
            f"t = {t0}: the first heading is unknown", stacklevel=2,
        )  # fmt: skip
        theta: Bounds = (-4.0, 4.0)
    else:
        theta = (heading - bounds.heading, heading + bounds.heading)
    e = bounds.gps
    x, y, th = compose_relative(
        [((g0[0] - e, g0[0] + e), (g0[1] - e, g0[1] + e), theta), _unmount()]
    )
    records: list[Record] = [PosePrior(0, x, y, th)]
    meas = tables.measurements
    scan_times = np.unique(meas[:, 0])
    keys = _keyframes(scan_times, t0, end, keyframe)

    def motion(ta: float, tb: float) -> RelativeBounds:
        return car_motion(t_in, inp[:, 1], inp[:, 2], ta, tb, bounds)

    first_row = np.searchsorted(meas[:, 0], keys)
    for i, tk in enumerate(keys):
        if i > 0:
            records.append(RelativePose(i - 1, i, *motion(keys[i - 1], tk)))
        upto = keys[i + 1] if i + 1 < len(keys) else end
        rows = range(first_row[i], len(meas))
        offsets: dict[float, RelativeBounds] = {}
        for r in rows:
            ts, rng, bearing, diameter = (float(v) for v in meas[r])
            if ts != tk and not (every_scan and tk < ts < upto):
                break
            if max_range is not None and rng > max_range:
                continue
            if ts not in offsets:
                offsets[ts] = MOUNT if ts == tk else compose_relative([motion(tk, ts), MOUNT])
            b = bearing - math.pi / 2
            records.append(
                Observation(
                    i,
                    "tree",
                    (max(rng - bounds.range, 0.0), rng + diameter / 2 + bounds.range),
                    (b - bounds.bearing, b + bounds.bearing),
                    offset=offsets[ts],
                )
            )
    gps = gps_at(tables.gps, np.asarray(keys))
    have = np.flatnonzero(~np.isnan(gps[:, 0]))
    reference = GpsReference(
        [int(i) for i in have], [keys[i] for i in have], gps[have].reshape(-1, 2)
    )
    return Log(records=records, path=os.fspath(tables.folder)), reference


def _unmount() -> RelativeBounds:
    """The rear axle in the frame of the laser (the inverse of ``MOUNT``)."""
    return ((-LASER_A, -LASER_A), (-LASER_B, -LASER_B), (0.0, 0.0))


def gps_inside(
    boxes: dict[int, tuple[Bounds, Bounds, Bounds]], reference: GpsReference, error: float
) -> tuple[int, int, list[tuple[int, float]]]:
    """How many GPS fixes lie in their pose's box, mapped to the antenna and grown by ``error``.

    Parameters
    ----------
    boxes : dict
        Pose id to its ``(x, y, theta)`` box (e.g. a result's envelope).
    reference : GpsReference
    error : float
        The GPS error allowed [m].

    Returns
    -------
    (int, int, list)
        Fixes inside, fixes compared (poses with a box and a fix), and the misses as
        ``(pose, distance from the grown box [m])``.
    """
    inside, compared, misses = 0, 0, []
    for pose, (gx, gy) in zip(reference.pose_ids, reference.xy.tolist(), strict=True):
        box = boxes.get(pose)
        if box is None:
            continue
        ax, ay, _ = compose_relative([box, MOUNT])
        dx = max(ax[0] - error - gx, gx - ax[1] - error, 0.0)
        dy = max(ay[0] - error - gy, gy - ay[1] - error, 0.0)
        compared += 1
        if dx == 0 and dy == 0:
            inside += 1
        else:
            misses.append((pose, math.hypot(dx, dy)))
    return inside, compared, misses
