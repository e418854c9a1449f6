"""Is a point estimate inside what is possible? Its poses and landmarks against the boxes.

The question a GTSAM (or any least-squares) user asks first of a guaranteed result: which
of my estimated poses and landmarks lie outside the boxes, and by how much. Containment is
decided exactly: each float value against the float bounds, headings modulo 2π (with 2π
enclosed between two rationals, :func:`cuikslam.interval.angles.angle_in`). The boxes
hold the truth whenever every measured interval does, so a value outside a box is
impossible under the log's bounds (for the true hypothesis), however well it fits.

Examples
--------
>>> import numpy as np, cuikslam
>>> h = cuikslam.Hypothesis(["L1"], [0, 1],
...     np.array([[[0.0, 0.0], [0.0, 0.0], [0.0, 0.0]], [[0.9, 1.1], [-0.1, 0.1], [6.0, 6.5]]]),
...     ["L1"], ["door"], np.array([[[4.0, 6.0], [-1.0, 1.0]]]))
>>> report = check_estimate(cuikslam.Solution([h]), {0: (0.0, 0.0, 0.0), 1: (1.2, 0.0, 0.1),
...                                                  "L1": (5.0, 0.5)})
>>> report.ok, report.poses_outside, report.landmarks_outside
(False, [1], [])
>>> print(report)
hypothesis 1 (not refuted): 2 poses and 1 landmark checked; 1 value outside its box
  pose 1 x = 1.2 outside [0.9, 1.1] by 0.09999999999999987
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cuikslam.interop.estimate import PointEstimate, landmark_key, pose_key
from cuikslam.interval.angles import angle_excess, angle_in
from cuikslam.outcome.solution import Hypothesis, Solution

__all__ = ["EstimateCheck", "Outside", "check_estimate"]


@dataclass(frozen=True)
class Outside:
    """One coordinate of the estimate outside its box.

    ``excess`` is how far outside, in floats (for ``theta``, the shortest way modulo 2π;
    at least one unit in the last place of the bound when rounding hides it).
    """

    kind: str
    """``"pose"`` or ``"landmark"``."""
    id: int | str
    coordinate: str
    """``"x"``, ``"y"`` or ``"theta"``."""
    value: float
    bounds: tuple[float, float]
    excess: float

    def __str__(self) -> str:
        lo, hi = self.bounds
        mod = " (mod 2pi)" if self.coordinate == "theta" else ""
        return (
            f"{self.kind} {self.id} {self.coordinate} = {self.value!r} outside "
            f"[{lo!r}, {hi!r}]{mod} by {self.excess!r}"
        )


@dataclass
class EstimateCheck:
    """Which poses and landmarks of an estimate lie outside a hypothesis' boxes."""

    rank: int
    """The hypothesis checked against (1 = the best-ranked; 0: one not in the solution)."""
    status: str
    tolerance: float = 0.0
    outside: list[Outside] = field(default_factory=list)
    poses_checked: int = 0
    landmarks_checked: int = 0
    poses_missing: list[int] = field(default_factory=list)
    """Poses of the hypothesis that the estimate has no value for."""
    landmarks_missing: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when every value checked lies in its box."""
        return not self.outside

    @property
    def poses_outside(self) -> list[int]:
        """Pose ids with a coordinate outside the box, in order, each once."""
        return list(dict.fromkeys(int(o.id) for o in self.outside if o.kind == "pose"))

    @property
    def landmarks_outside(self) -> list[str]:
        """Landmark ids with a coordinate outside the box, in order, each once."""
        return list(dict.fromkeys(str(o.id) for o in self.outside if o.kind == "landmark"))

    def __str__(self) -> str:
        def count(n: int, noun: str) -> str:
            return f"{n} {noun}" if n == 1 else f"{n} {noun}s"

        head = (
            f"hypothesis {self.rank} ({self.status}): {count(self.poses_checked, 'pose')} and "
            f"{count(self.landmarks_checked, 'landmark')} checked; "
        )
        head += (
            "every value inside its box"
            if self.ok
            else f"{count(len(self.outside), 'value')} outside "
            + ("its box" if len(self.outside) == 1 else "their boxes")
        )
        if self.tolerance:
            head += f" (tolerance {self.tolerance!r})"
        lines = [head, *(f"  {o}" for o in self.outside)]
        if self.poses_missing:
            lines.append(f"  not in the estimate: {count(len(self.poses_missing), 'pose')}")
        if self.landmarks_missing:
            lines.append(f"  not in the estimate: {count(len(self.landmarks_missing), 'landmark')}")
        return "\n".join(lines)


def _lookup(
    estimate: Any, hypothesis: Hypothesis
) -> tuple[dict[int, Sequence[float]], dict[str, Sequence[float]]]:
    """The estimate's poses and landmarks by id, whatever form it came in."""
    if isinstance(estimate, PointEstimate):
        poses = dict(zip(estimate.pose_ids, estimate.poses_xyt.tolist(), strict=True))
        return poses, dict(zip(estimate.landmark_ids, estimate.landmarks_xy.tolist(), strict=True))
    if isinstance(estimate, Mapping):
        poses = {k: v for k, v in estimate.items() if isinstance(k, int | np.integer)}
        marks = {k: v for k, v in estimate.items() if isinstance(k, str)}
        return poses, marks
    if hasattr(estimate, "exists") and hasattr(estimate, "atPose2"):  # gtsam.Values
        poses = {}
        for p in hypothesis.pose_ids:
            if estimate.exists(pose_key(p)):
                value = estimate.atPose2(pose_key(p))
                poses[p] = (value.x(), value.y(), value.theta())
        marks = {
            m: tuple(np.asarray(estimate.atPoint2(landmark_key(j)), dtype=float))
            for j, m in enumerate(hypothesis.landmark_ids)
            if estimate.exists(landmark_key(j))
        }
        return poses, marks
    raise TypeError(
        "the estimate must be a gtsam.Values, a PointEstimate, or a mapping of pose ids "
        f"(int) to (x, y, theta) and landmark ids (str) to (x, y); got {type(estimate).__name__}"
    )


def _widen(lo: float, hi: float, tolerance: float) -> tuple[float, float]:
    """``[lo - tolerance, hi + tolerance]`` rounded outward (unchanged for 0)."""
    if tolerance == 0:
        return lo, hi
    return math.nextafter(lo - tolerance, -math.inf), math.nextafter(hi + tolerance, math.inf)


def _outside_linear(value: float, lo: float, hi: float, tolerance: float) -> float | None:
    """How far ``value`` lies outside ``[lo, hi]``; None inside, or within ``tolerance``
    of it (exact float comparison)."""
    wide_lo, wide_hi = _widen(lo, hi, tolerance)
    if wide_lo <= value <= wide_hi:
        return None
    if math.isnan(value):
        return math.nan
    return lo - value if value < lo else value - hi


def _outside_angle(value: float, lo: float, hi: float, tolerance: float) -> float | None:
    """How far the angle ``value`` lies outside ``[lo, hi]`` modulo 2π; None inside, or
    within ``tolerance`` of it."""
    if math.isfinite(value) and angle_in(*_widen(lo, hi, tolerance), value):
        return None
    if not math.isfinite(value):
        return math.nan
    excess = angle_excess(value, lo, hi)
    return excess if excess > 0 else math.ulp(max(abs(lo), abs(hi)))


def check_estimate(
    solution: Solution, estimate: Any, hypothesis: int | Hypothesis = 0, tolerance: float = 0.0
) -> EstimateCheck:
    """Say which poses and landmarks of ``estimate`` lie outside the boxes of a hypothesis.

    Parameters
    ----------
    solution : Solution
        A result (``cuikslam.solve`` or ``cuikslam.read_result_file``).
    estimate : gtsam.Values, PointEstimate or mapping
        The estimate: a ``gtsam.Values`` keyed as :func:`cuikslam.interop.gtsam.factor_graph`
        keys it (pose ``p`` at ``X(p)``, the hypothesis' ``j``-th landmark at ``L(j)``); a
        :class:`~cuikslam.interop.estimate.PointEstimate`; or a mapping of pose ids (int)
        to ``(x, y, theta)`` and landmark ids (str) to ``(x, y)``.
    hypothesis : int or Hypothesis
        Which hypothesis: an index into ``solution.hypotheses`` (default 0, the best) or
        the hypothesis itself.
    tolerance : float
        Count a value within ``tolerance`` of its box as inside (default 0: exact
        containment). GTSAM keeps a heading as its cosine and sine, so a heading known
        exactly may come back one unit in the last place away; a tolerance of 1e-12 says
        "inside up to rounding".

    Returns
    -------
    EstimateCheck
        The coordinates outside their boxes (empty: the estimate is inside what is
        possible), and what was checked; ``print`` it for a summary.

    Raises
    ------
    ValueError
        When the solution has no such hypothesis, or ``tolerance`` is not a number >= 0.
    """
    if not (isinstance(tolerance, int | float) and 0 <= tolerance < math.inf):
        raise ValueError(f"tolerance must be a finite number >= 0, got {tolerance!r}")
    if isinstance(hypothesis, Hypothesis):
        chosen = hypothesis
        rank = next((i + 1 for i, h in enumerate(solution.hypotheses) if h is chosen), 0)
    else:
        if not -len(solution.hypotheses) <= hypothesis < len(solution.hypotheses):
            raise ValueError(
                f"the solution has {len(solution.hypotheses)} hypotheses; "
                f"there is no hypothesis {hypothesis}"
            )
        chosen = solution.hypotheses[hypothesis]
        rank = hypothesis % len(solution.hypotheses) + 1
    poses, marks = _lookup(estimate, chosen)
    report = EstimateCheck(rank, chosen.status, tolerance)
    for pose_id, box in zip(chosen.pose_ids, chosen.poses, strict=True):
        if pose_id not in poses:
            report.poses_missing.append(pose_id)
            continue
        report.poses_checked += 1
        for j, (name, test) in enumerate(
            (("x", _outside_linear), ("y", _outside_linear), ("theta", _outside_angle))
        ):
            value, lo, hi = float(poses[pose_id][j]), float(box[j, 0]), float(box[j, 1])
            excess = test(value, lo, hi, tolerance)
            if excess is not None:
                report.outside.append(Outside("pose", pose_id, name, value, (lo, hi), excess))
    for landmark_id, box in zip(chosen.landmark_ids, chosen.landmarks, strict=True):
        if landmark_id not in marks:
            report.landmarks_missing.append(landmark_id)
            continue
        report.landmarks_checked += 1
        for j, name in enumerate(("x", "y")):
            value, lo, hi = float(marks[landmark_id][j]), float(box[j, 0]), float(box[j, 1])
            excess = _outside_linear(value, lo, hi, tolerance)
            if excess is not None:
                report.outside.append(
                    Outside("landmark", landmark_id, name, value, (lo, hi), excess)
                )
    return report
