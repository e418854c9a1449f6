"""How a solve did against the ground truth: containment, box widths, association.

:func:`evaluate` compares a :class:`~cuikslam.outcome.solution.Solution` with a
:class:`~cuikslam.simulate.truth.GroundTruth`:

* **Containment.** The share of poses and landmarks whose truth lies inside their box,
  compared exactly as :func:`~cuikslam.outcome.solution.check_truth` does (true values
  as exact rationals, headings modulo an exact 2π). Truth files of real runs may cover
  only some poses (Vicon gaps): only poses with a truth are counted, and the poses
  without one are counted apart.
* **Widths** of the pose boxes (x, y, θ) and landmark boxes (x, y): median, 95th
  percentile and maximum, over the whole run and over consecutive stretches of it.
* **Association** (unknown correspondence): the rank, among the reported hypotheses, of
  the one whose partition of the observations into landmarks is the true one (with the
  landmarks the log names keeping their names, as the truth check of ``solve`` does), and
  the share of observations the best-ranked hypothesis associates correctly. An
  observation is associated correctly when it follows what it truly follows: the same
  previous sighting of its landmark, the same named landmark, or nothing (a first
  sighting); the names given to new landmarks play no part.

The hypothesis evaluated for containment and widths is the true one when it is among
the reported hypotheses, else the best-ranked one (its boxes need not contain the truth).
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cuikslam.outcome.solution import OUTLIER, Hypothesis, Solution, _check_pose, _check_xy
from cuikslam.outcome.summary import _follows
from cuikslam.results.association import paired_landmarks, rank_of
from cuikslam.simulate.truth import GroundTruth

__all__ = ["Evaluation", "WidthStats", "evaluate", "evaluation_to_json"]

SEGMENTS = 10
"""Consecutive stretches of the run the widths are also summarised over."""


@dataclass
class WidthStats:
    """Median, 95th percentile and maximum of some box widths (``inf``: unbounded)."""

    median: float
    p95: float
    max: float
    count: int

    @classmethod
    def of(cls, widths: np.ndarray) -> WidthStats:
        """The statistics of ``widths`` (NaN for no widths at all)."""
        w = np.asarray(widths, dtype=float).ravel()
        if w.size == 0:
            return cls(math.nan, math.nan, math.nan, 0)
        # The median as `cuikslam solve` prints it (results.overview: the mean of the two
        # middle widths of an even count); "higher" picks a sample for the 95th percentile,
        # so an unbounded width never meets inf - inf.
        return cls(
            float(np.median(w)),
            float(np.percentile(w, 95, method="higher")),
            float(w.max()),
            int(w.size),
        )


@dataclass
class Evaluation:
    """What :func:`evaluate` measured (see the module docstring)."""

    evaluated_rank: int
    """Rank (1 = best) of the hypothesis whose boxes were evaluated."""
    true_rank: int | None
    """Rank of the true correspondence among the reported hypotheses; None if absent."""
    reported: int
    survivors: int
    complete: bool
    pose_ids: list[int]
    """The evaluated hypothesis' poses, in its order."""
    pose_widths: np.ndarray
    """(n_poses, 3) widths of x, y, θ."""
    pose_inside: list[bool | None]
    """Per pose: truth inside its box, or None when the truth has no value for it."""
    landmarks_with_truth: int
    landmarks_inside: int
    landmarks_without_truth: int
    landmark_widths: np.ndarray
    """(n_landmarks, 2) widths of x, y."""
    truth_poses_not_in_result: int
    misses: list[str]
    observations: int
    correct_associations: int | None
    """Observations the best-ranked hypothesis associates correctly (None: no truth)."""
    notes: list[str] = field(default_factory=list)
    hull_inside: int | None = None
    """Poses whose truth lies in their box whatever the correspondence (the result's
    ``correspondence.pose_hull``, over every survivor); None without that hull."""
    hull_checked: int | None = None
    doubtful: int = 0
    """Observations from an uncertain sensor offset, whose truth cannot be checked, that the
    evaluated true hypothesis takes as sightings: when its boxes miss the truth, one of
    them may be an outlier, so nothing can be said."""

    @property
    def poses_with_truth(self) -> int:
        return sum(v is not None for v in self.pose_inside)

    @property
    def poses_inside(self) -> int:
        return sum(v is True for v in self.pose_inside)

    @property
    def poses_without_truth(self) -> int:
        return sum(v is None for v in self.pose_inside)

    @property
    def evaluated_is_true(self) -> bool:
        return self.true_rank is not None and self.true_rank == self.evaluated_rank

    @property
    def guarantee_held(self) -> bool | None:
        """False when the guarantee visibly failed: the true hypothesis has a box missing
        its truth, a complete search reported every survivor and the true
        correspondence is not among them, or a complete search's pose hull over every
        survivor misses a true pose. None when nothing can be said (the true
        correspondence was not reported: unreported or the search was incomplete)."""
        if self.complete and self.hull_checked and self.hull_inside < self.hull_checked:
            return False  # the hull over every survivor misses a true pose
        sole = self.complete and self.survivors == self.reported == 1
        if self.evaluated_is_true or (sole and self.correct_associations is None):
            if self.misses and self.doubtful:
                return None  # an unchecked observation may be the outlier
            return not self.misses  # a sole survivor of a complete search is the true one
        if self.correct_associations is not None and self.complete:
            if self.survivors <= self.reported:
                return False
        return None

    def widths(self) -> dict[str, WidthStats]:
        """Width statistics of pose x, y, θ and landmark x, y."""
        pw, lw = self.pose_widths, self.landmark_widths
        return {
            "x": WidthStats.of(pw[:, 0]),
            "y": WidthStats.of(pw[:, 1]),
            "theta": WidthStats.of(pw[:, 2]),
            "landmark_x": WidthStats.of(lw[:, 0]),
            "landmark_y": WidthStats.of(lw[:, 1]),
        }

    def over_time(self, segments: int = SEGMENTS) -> list[dict[str, Any]]:
        """Median widths and containment over ``segments`` consecutive stretches of poses."""
        n = len(self.pose_ids)
        out = []
        for part in np.array_split(np.arange(n), min(segments, n)) if n else []:
            inside = [self.pose_inside[i] for i in part]
            out.append(
                {
                    "first_pose": self.pose_ids[int(part[0])],
                    "last_pose": self.pose_ids[int(part[-1])],
                    "poses": int(part.size),
                    "median_x": WidthStats.of(self.pose_widths[part, 0]).median,
                    "median_y": WidthStats.of(self.pose_widths[part, 1]).median,
                    "median_theta": WidthStats.of(self.pose_widths[part, 2]).median,
                    "with_truth": sum(v is not None for v in inside),
                    "inside": sum(v is True for v in inside),
                }
            )
        return out


def _pose_inside(pose_id: int, box: np.ndarray, value: tuple, misses: list[str]) -> bool:
    """Whether the exact true pose ``value`` lies in ``box`` (heading modulo 2π); each
    coordinate outside adds a line to ``misses``."""
    before = len(misses)
    _check_pose(pose_id, box, value, misses)
    return len(misses) == before


def _widths(boxes: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore"):
        return boxes[..., 1] - boxes[..., 0]


def _landmark_truth(
    h: Hypothesis, truth: GroundTruth, named: Collection[str]
) -> dict[str, str | None]:
    """Each landmark of ``h`` → the true landmark it is, or None when that is not one
    (a wrong hypothesis merging several) or unknown."""
    pairs = paired_landmarks(h, truth)  # by id for a truth without assignment
    known = set(truth.landmark_ids)
    out: dict[str, str | None] = {}
    for m in h.landmark_ids:
        ids = set(pairs.get(m, ()))
        if m in named and m in known:
            ids.add(m)
        out[m] = next(iter(ids)) if len(ids) == 1 else None
    return out


def evaluate(
    solution: Solution,
    truth: GroundTruth,
    named: Collection[str] = frozenset(),
    outside: Collection[int] = (),
    unchecked: Collection[int] = (),
) -> Evaluation:
    """Measure ``solution`` against ``truth`` (see the module docstring).

    Parameters
    ----------
    solution : Solution
        A solve's result, at least one hypothesis.
    truth : GroundTruth
        True poses (any subset of the result's), landmarks, and the true landmark of each
        observation (or no assignment at all: then association is not measured and
        landmarks are matched by id).
    named : collection of str
        Landmark ids the log names: they keep their names when partitions are compared.
    outside : collection of int
        With an ``outliers`` declaration and unknown correspondence, the observations that
        miss their truth: the true hypothesis takes them as outliers (see
        :func:`~cuikslam.results.association.rank_of`).
    unchecked : collection of int
        The observations whose truth cannot be checked
        (:func:`~cuikslam.results.association.true_outliers`).

    Returns
    -------
    Evaluation

    Raises
    ------
    ValueError
        If the solution has no hypothesis, the truth's assignment does not have one entry
        per observation, or no pose of the result has a truth.
    """
    if not solution.hypotheses:
        raise ValueError("the result has no hypothesis to evaluate")
    best = solution.best
    n_obs = len(best.assignment)
    if truth.assignment and len(truth.assignment) != n_obs:
        raise ValueError(
            f"the truth assigns {len(truth.assignment)} observations, the result {n_obs}"
        )
    truth_of_pose = dict(zip(truth.pose_ids, truth.exact_poses(), strict=True))
    if not set(truth_of_pose) & set(best.pose_ids):
        raise ValueError(
            f"none of the truth's {len(truth_of_pose)} poses is a pose of the result "
            f"(poses {best.pose_ids[0]}..{best.pose_ids[-1]})"
            if best.pose_ids
            else "the result has no poses"
        )

    true_rank = None
    if truth.assignment or n_obs == 0:
        true_rank = rank_of(solution.hypotheses, truth.assignment, named, outside, unchecked)
    rank = true_rank or 1
    h = solution.hypotheses[rank - 1]

    misses: list[str] = []
    inside: list[bool | None] = []
    for pose_id, box in zip(h.pose_ids, h.poses, strict=True):
        value = truth_of_pose.get(pose_id)
        if value is None:
            inside.append(None)
            continue
        inside.append(_pose_inside(pose_id, box, value, misses))

    hull_inside = hull_checked = None
    hull = (solution.correspondence or {}).get("pose_hull")
    if hull is not None:
        boxes = np.asarray(hull, dtype=float)
        if boxes.shape == (len(best.pose_ids), 3, 2):
            hull_inside = hull_checked = 0
            for pose_id, box in zip(sorted(best.pose_ids), boxes, strict=True):  # id order
                value = truth_of_pose.get(pose_id)
                if value is not None:
                    hull_checked += 1
                    hull_inside += _pose_inside(pose_id, box, value, [])

    notes: list[str] = []
    mapping = _landmark_truth(h, truth, named)
    with_truth = landmark_inside = 0
    for m, box in zip(h.landmark_ids, h.landmarks, strict=True):
        theirs = mapping[m]
        if theirs is None:
            continue
        with_truth += 1
        before = len(misses)
        _check_xy(f"landmark {m}", box, truth.exact_landmark(theirs), misses)
        landmark_inside += len(misses) == before
    if not truth.assignment and n_obs:
        notes.append("the truth has no assignment: association not measured")

    correct = None
    if truth.assignment or n_obs == 0:
        marked = [OUTLIER if i in set(outside) else a for i, a in enumerate(truth.assignment)]
        true_follows = _follows(marked, set(named))
        ours = _follows(list(best.assignment), set(named))
        correct = sum(a == b for a, b in zip(ours, true_follows, strict=True))

    result_poses = set(h.pose_ids)
    return Evaluation(
        evaluated_rank=rank,
        true_rank=true_rank,
        reported=len(solution.hypotheses),
        survivors=int(solution.statistics.get("survivors", len(solution.hypotheses))),
        complete=solution.complete,
        pose_ids=list(h.pose_ids),
        pose_widths=_widths(h.poses).reshape(len(h.pose_ids), 3),
        pose_inside=inside,
        landmarks_with_truth=with_truth,
        landmarks_inside=landmark_inside,
        landmarks_without_truth=h.n_landmarks - with_truth,
        landmark_widths=_widths(h.landmarks).reshape(h.n_landmarks, 2),
        truth_poses_not_in_result=sum(p not in result_poses for p in truth_of_pose),
        misses=misses,
        observations=n_obs,
        correct_associations=correct,
        notes=notes,
        hull_inside=hull_inside,
        hull_checked=hull_checked,
        doubtful=len(set(unchecked) - set(h.outliers)) if true_rank == rank else 0,
    )


def _number(value: float) -> float | None:
    """JSON has no infinity or NaN: those are written as null."""
    return float(value) if math.isfinite(value) else None


def evaluation_to_json(ev: Evaluation) -> dict[str, Any]:
    """The evaluation as plain JSON-ready objects (``cuikslam evaluate --json``)."""

    def share(part: int, whole: int) -> float | None:
        return part / whole if whole else None

    return {
        "evaluated_hypothesis": ev.evaluated_rank,
        "true_rank": ev.true_rank,
        "reported": ev.reported,
        "survivors": ev.survivors,
        "complete": ev.complete,
        "guarantee_held": ev.guarantee_held,
        "poses": {
            "total": len(ev.pose_ids),
            "with_truth": ev.poses_with_truth,
            "inside": ev.poses_inside,
            "share_inside": share(ev.poses_inside, ev.poses_with_truth),
            "without_truth": ev.poses_without_truth,
            "truth_poses_not_in_result": ev.truth_poses_not_in_result,
        },
        "landmarks": {
            "total": len(ev.landmark_widths),
            "with_truth": ev.landmarks_with_truth,
            "inside": ev.landmarks_inside,
            "share_inside": share(ev.landmarks_inside, ev.landmarks_with_truth),
            "without_truth": ev.landmarks_without_truth,
        },
        "widths": {
            k: {"median": _number(s.median), "p95": _number(s.p95), "max": _number(s.max)}
            for k, s in ev.widths().items()
        },
        "over_time": [
            {k: (_number(v) if isinstance(v, float) else v) for k, v in seg.items()}
            for seg in ev.over_time()
        ],
        "pose_hull": {"with_truth": ev.hull_checked, "inside": ev.hull_inside},
        "association": {
            "observations": ev.observations,
            "correct_by_best": ev.correct_associations,
            "share_correct_by_best": (
                None
                if ev.correct_associations is None
                else share(ev.correct_associations, ev.observations)
            ),
        },
        "misses": ev.misses,
        "notes": ev.notes,
    }
