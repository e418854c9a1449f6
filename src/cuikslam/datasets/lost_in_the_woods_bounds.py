"""Lost in the Woods bounds measured on a part of the run against Vicon, and checked on another.

Three standard deviations per 10 Hz sample, composed soundly over a 1 s keyframe, give a
heading interval of ±0.27 rad per keyframe, while the wheel odometry of the run is never
more than 0.05 rad off over a keyframe (its errors partly cancel within a second). So the
calibrated model bounds the *composed* motion, not each sample:

* **Motion.** For a stretch of samples ``a .. j`` (a keyframe step, or the part of one up
  to an observation's sample), the nominal relative pose is the odometry composed at face
  value (:func:`cuikslam.motion.compose_steps` on the readings, driving along the heading
  plus ``DRIVE_OFFSET``), and the truth lies within

  - ``move_x + move_x_per_metre · travelled`` of it forward (x in the frame of ``a``),
  - ``move_y + move_y_per_metre · travelled`` sideways,
  - ``move_theta + move_theta_per_radian · turned`` in heading,

  where ``travelled`` = Σ |v| dt and ``turned`` = Σ |ω| dt over the stretch (the errors
  grow with the distance and the turning: a scale error of the wheels).
  ``max_samples`` is the longest stretch calibrated: an import with longer keyframes is
  refused, since the constant parts were measured on shorter ones.
* **Range, bearing**: one bound each, on the errors of every post sighting against the
  range and bearing from the laser (0.219 m ahead of the Vicon pose) to the post.

:func:`calibrate_lost_in_the_woods` picks, for each of the five quantities, the bound
that holds a share ``quantile`` of the part's stretches or sightings and is the narrowest
on average (for the motion: the constant part tried at 41 quantiles of the errors, the
part per metre or per radian then the smallest that covers the share).
:func:`count_outside_lost_in_the_woods` counts, on another part, the stretches and
sightings whose interval misses the truth: the honest figure of how well they carry over.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from cuikslam.datasets._litw_file import load_dataset
from cuikslam.datasets.calibrate import Calibration, _round_up, _stats
from cuikslam.errors import InputFileError
from cuikslam.interval.angles import wrap_angle
from cuikslam.motion import compose_steps

__all__ = [
    "LitwBounds",
    "LitwOutside",
    "calibrate_lost_in_the_woods",
    "count_outside_lost_in_the_woods",
    "nominal_move",
]

DRIVE_OFFSET = -0.079
"""Angle [rad] from the Vicon heading to the direction the wheels drive (measured)."""
MOTION_FIELDS = ("x", "y", "theta")


@dataclass(frozen=True)
class LitwBounds:
    """Calibrated bounds of Lost in the Woods (see the module docstring)."""

    range: float
    bearing: float
    move_x: float
    move_x_per_metre: float
    move_y: float
    move_y_per_metre: float
    move_theta: float
    move_theta_per_radian: float
    max_samples: int

    @classmethod
    def from_dict(cls, values: dict[str, float], path: str | os.PathLike[str]) -> LitwBounds:
        """The bounds of a bounds file's ``"bounds"`` object (every field needed)."""
        missing = [f.name for f in fields(cls) if f.name not in values]
        if missing:
            raise InputFileError(path, None, f"the bounds file lacks {', '.join(missing)}")
        samples = values["max_samples"]
        if samples != int(samples) or samples < 1:
            raise InputFileError(
                path, None, f"max_samples must be a whole number >= 1, got {samples}"
            )
        return cls(**{**values, "max_samples": int(samples)})

    def motion(self, travelled: float, turned: float) -> tuple[float, float, float]:
        """Half-widths (x, y, theta) around the nominal move of a stretch."""
        return (
            self.move_x + self.move_x_per_metre * travelled,
            self.move_y + self.move_y_per_metre * travelled,
            self.move_theta + self.move_theta_per_radian * turned,
        )


def nominal_move(
    v: np.ndarray, om: np.ndarray, t: np.ndarray
) -> tuple[tuple[float, float, float], float, float]:
    """The odometry of one stretch composed at face value: the centre of the relative pose
    (dx, dy, dtheta), the distance travelled and the angle turned."""
    box = np.stack([v, v], axis=-1)
    turn = np.stack([om, om], axis=-1)
    move = compose_steps(box, turn, t, (DRIVE_OFFSET, DRIVE_OFFSET))
    centre = tuple(0.5 * lo + 0.5 * hi for lo, hi in move)
    dt = np.diff(t)
    return centre, float(np.sum(np.abs(v) * dt)), float(np.sum(np.abs(om) * dt))


@dataclass
class _Errors:
    """Errors of a part's stretches (with their lengths) and sightings."""

    travelled: np.ndarray
    turned: np.ndarray
    move: np.ndarray
    """(n, 3): truth minus nominal, x and y in the frame of the stretch's start, theta."""
    where: list[tuple[int, int]]
    """First and last sample of each stretch."""
    range: np.ndarray
    bearing: np.ndarray
    sighting: list[tuple[int, int]]
    """Sample and post of each sighting."""


def _part(path: str | os.PathLike[str], n: int, start: int, steps: int | None) -> tuple[int, int]:
    end = n - 1 if steps is None else min(start + steps, n - 1)
    if start < 0 or end <= start:
        raise InputFileError(path, None, f"the part {start}..{end} is empty or outside 0..{n - 1}")
    return start, end


def _errors(data: dict[str, np.ndarray], start: int, end: int, keyframe: int) -> _Errors:
    """Every stretch from a keyframe sample to a later sample of its keyframe step, and
    every post sighting, with Vicon at both ends (stretches) or at the sample (sightings)."""
    t = data["t"].ravel().astype(float)
    v, om = data["v"].ravel().astype(float), data["om"].ravel().astype(float)
    x, y = data["x_true"].ravel(), data["y_true"].ravel()
    theta = data["th_true"].ravel()
    valid = data["true_valid"].ravel() != 0
    travelled, turned, move, where = [], [], [], []
    for a in range(start, end, keyframe):
        if not valid[a]:
            continue
        c, s = math.cos(theta[a]), math.sin(theta[a])
        for j in range(a + 1, min(a + keyframe, end) + 1):
            if not valid[j]:
                continue
            (mx, my, mt), dist, turn = nominal_move(v[a:j], om[a:j], t[a : j + 1])
            dxw, dyw = x[j] - x[a], y[j] - y[a]
            truth = (c * dxw + s * dyw, -s * dxw + c * dyw, theta[j] - theta[a])
            move.append((truth[0] - mx, truth[1] - my, wrap_angle(truth[2] - mt)))
            travelled.append(dist)
            turned.append(turn)
            where.append((a, j))
    d = float(np.asarray(data["d"]).ravel()[0])
    ranges, bearings = np.asarray(data["r"], float), np.asarray(data["b"], float)
    posts = np.asarray(data["l"], float)
    sample, post = np.nonzero((ranges[start : end + 1] > 0) & valid[start : end + 1, None])
    sample = sample + start
    sx = x[sample] + d * np.cos(theta[sample])
    sy = y[sample] + d * np.sin(theta[sample])
    px, py = posts[post, 0], posts[post, 1]
    range_error = ranges[sample, post] - np.hypot(px - sx, py - sy)
    direction = np.arctan2(py - sy, px - sx) - theta[sample]
    bearing_error = np.array([wrap_angle(e) for e in bearings[sample, post] - direction])
    return _Errors(
        np.array(travelled), np.array(turned), np.array(move).reshape(-1, 3), where,
        range_error, bearing_error, list(zip(sample.tolist(), post.tolist(), strict=True)),
    )  # fmt: skip


def _fit(error: np.ndarray, scale: np.ndarray, quantile: float) -> tuple[float, float]:
    """(a, c), rounded up, such that ``|error| <= a + c * scale`` for the share ``quantile``
    of the stretches, with the smallest mean bound among the candidates."""
    e = np.abs(error)
    best: tuple[float, float, float] | None = None
    for a in np.unique(np.quantile(e, np.linspace(0.0, 1.0, 41), method="higher")):
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            need = np.where(e <= a, 0.0, (e - a) / scale)  # inf: no slope covers it
        c = float(np.quantile(need, quantile, method="higher"))
        if not math.isfinite(c):
            continue
        cost = float(a) + c * float(np.mean(scale))
        if best is None or cost < best[0]:
            best = (cost, float(a), c)
    assert best is not None  # the largest error as the constant part always covers
    return _round_up(best[1]), _round_up(best[2])


@dataclass
class LitwOutside:
    """Stretches and sightings of a part whose interval misses the truth."""

    moves: int
    moves_checked: int
    ranges: int
    bearings: int
    sightings_checked: int
    worst: list[str]
    """The largest misses, described (sample numbers are the file's)."""

    def describe(self) -> str:
        return (
            f"{self.moves} of {self.moves_checked} odometry stretches, {self.ranges} ranges "
            f"and {self.bearings} bearings of {self.sightings_checked} sightings outside"
        )

    def to_json(self) -> dict[str, Any]:
        return dict(vars(self))


def _outside(errors: _Errors, bounds: LitwBounds, shown: int = 10) -> LitwOutside:
    half = np.array(
        [bounds.motion(d, r) for d, r in zip(errors.travelled, errors.turned, strict=True)]
    )
    excess = np.abs(errors.move) - half.reshape(-1, 3)
    bad_moves = np.flatnonzero(np.any(excess > 0, axis=1))
    bad_range = np.abs(errors.range) > bounds.range
    bad_bearing = np.abs(errors.bearing) > bounds.bearing
    worst = []
    for i in bad_moves[np.argsort(-np.max(excess[bad_moves], axis=1))][:shown]:
        a, j = errors.where[i]
        k = int(np.argmax(excess[i]))
        worst.append(
            f"samples {a}..{j}: {MOTION_FIELDS[k]} off by {abs(errors.move[i, k]):.4g}, "
            f"bound {half[i, k]:.4g}"
        )
    for i in np.flatnonzero(bad_range | bad_bearing)[:shown]:
        j, p = errors.sighting[i]
        worst.append(
            f"sample {j}, post P{p}: range off by {errors.range[i]:+.3g} m, bearing by "
            f"{errors.bearing[i]:+.3g} rad"
        )
    return LitwOutside(
        int(bad_moves.size), len(errors.where), int(bad_range.sum()), int(bad_bearing.sum()),
        int(errors.range.size), worst,
    )  # fmt: skip


def calibrate_lost_in_the_woods(
    path: str | os.PathLike[str],
    *,
    start: int = 0,
    steps: int | None = None,
    keyframe: int = 10,
    quantile: float = 1.0,
    motion_quantile: float = 1.0,
    motion_margin: float = 1.0,
) -> Calibration:
    """Measure the bounds on samples ``start .. start + steps`` (see the module docstring).

    Parameters
    ----------
    path : path-like
        ``dataset2.mat``.
    keyframe : int
        The longest stretch measured, in samples: imports may use keyframes up to it.
    quantile : float
        Share (0 < q <= 1) of the part's sightings the range and bearing bounds must
        hold; 1 takes the maxima. Below 1 the rest are outliers to declare.
    motion_quantile : float
        The same for the stretches of odometry (default 1: the log's ``outliers`` record
        covers observations only, so a move outside its interval cannot be declared).
    motion_margin : float
        Factor (>= 1) on the motion bounds, for what the part did not show: on the run's
        second half, 16 of 6,077 stretches fall outside the first half's bounds, 1 at
        a factor of 1.5, none at 2.

    Raises
    ------
    InputFileError
        If the part is empty or has no stretch or sighting with Vicon truth.
    ValueError
        If ``quantile`` is not in (0, 1].
    """
    for q in (quantile, motion_quantile):
        if not 0 < q <= 1:
            raise ValueError(f"a quantile must be in (0, 1], got {q}")
    if not motion_margin >= 1:
        raise ValueError(f"the motion margin must be at least 1, got {motion_margin}")
    data = load_dataset(path)
    start, end = _part(path, data["t"].size, start, steps)
    errors = _errors(data, start, end, keyframe)
    if not errors.where or errors.range.size == 0:
        raise InputFileError(
            path, None, f"samples {start}..{end}: no stretch or sighting with truth"
        )
    fitted = [
        tuple(_round_up(motion_margin * v) for v in _fit(e, scale, motion_quantile))
        for e, scale in (
            (errors.move[:, 0], errors.travelled),
            (errors.move[:, 1], errors.travelled),
            (errors.move[:, 2], errors.turned),
        )
    ]
    bounds = LitwBounds(
        range=_round_up(float(np.quantile(np.abs(errors.range), quantile, method="higher"))),
        bearing=_round_up(float(np.quantile(np.abs(errors.bearing), quantile, method="higher"))),
        move_x=fitted[0][0], move_x_per_metre=fitted[0][1],
        move_y=fitted[1][0], move_y_per_metre=fitted[1][1],
        move_theta=fitted[2][0], move_theta_per_radian=fitted[2][1],
        max_samples=keyframe,
    )  # fmt: skip
    return Calibration(
        bounds=bounds,
        calibrated_on={
            "file": os.fspath(path),
            "start": start,
            "end": end,
            "keyframe": keyframe,
            "quantile": quantile,
            "motion_quantile": motion_quantile,
            "motion_margin": motion_margin,
        },
        errors={
            "range": _stats(errors.range),
            "bearing": _stats(errors.bearing),
            **{f"move_{name}": _stats(errors.move[:, i]) for i, name in enumerate(MOTION_FIELDS)},
        },
        outside=_outside(errors, bounds),
    )


def count_outside_lost_in_the_woods(
    path: str | os.PathLike[str],
    bounds: LitwBounds,
    *,
    start: int = 0,
    steps: int | None = None,
    keyframe: int | None = None,
) -> LitwOutside:
    """Count the stretches (keyframe steps of ``keyframe`` samples, default the calibrated
    length, and their parts) and sightings of samples ``start .. start + steps`` whose
    interval misses the truth."""
    data = load_dataset(path)
    start, end = _part(path, data["t"].size, start, steps)
    return _outside(_errors(data, start, end, keyframe or bounds.max_samples), bounds)
