"""What a solve returns: the surviving hypotheses, each with its boxes, and statistics.

Boxes are NumPy arrays whose last axis is ``(lo, hi)``: ``poses`` has shape
``(n_poses, 3, 2)`` for (x, y, theta), ``landmarks`` has shape ``(n_landmarks, 2, 2)``.
Heading boxes are unwrapped: the true heading is congruent (mod 2 pi) to a value inside.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from decimal import Decimal, localcontext
from fractions import Fraction

import numpy as np

from cuikslam.interval.angles import angle_in
from cuikslam.log.records import RESERVED_LANDMARK_ID
from cuikslam.messages import Message

__all__ = [
    "NOT_REFUTED",
    "OUTLIER",
    "PROVEN",
    "Envelope",
    "ExactLike",
    "Hypothesis",
    "Solution",
    "TruthReport",
    "bounds_to_json",
    "check_envelope",
    "check_truth",
    "no_hypothesis",
]

PROVEN = "proven consistent"
"""A point satisfying every constraint was found and verified in interval arithmetic."""
NOT_REFUTED = "not refuted"
"""Narrowing did not prove the hypothesis impossible (nor was a witness verified)."""
OUTLIER = RESERVED_LANDMARK_ID
"""In an assignment: the observation is taken as an outlier (it explains nothing; only with
an ``outliers`` declaration and unknown correspondence). No landmark may have this id."""


@dataclass
class Hypothesis:
    """One correspondence hypothesis (a kinematic graph) and its narrowed boxes."""

    assignment: list[str]
    """Landmark id of each observation, in log order (``OUTLIER`` for one it takes as an
    outlier)."""
    pose_ids: list[int]
    poses: np.ndarray
    landmark_ids: list[str]
    landmark_classes: list[str]
    landmarks: np.ndarray
    status: str = NOT_REFUTED
    witness: dict[str, np.ndarray] | None = None
    """A verified solution point (``poses_xyt``, ``landmarks_xy``) when ``status`` is PROVEN."""
    consistency: str = ""
    """The consistency level these boxes reach (``hull``, ``lp``, ``lp-split``)."""
    fit: float = math.nan
    """Least-squares cost of the world that best explains its readings: the sum of the
    squared distances of every measured value from its interval's centre, in half-widths
    (the objective of a least-squares back end with those as standard deviations), as far
    as :func:`~cuikslam.witness.fit_hypotheses` got within its budget; NaN when
    not computed. It ranks hypotheses that explain the log equally parsimoniously."""

    @property
    def n_landmarks(self) -> int:
        return len(self.landmark_ids)

    @property
    def outliers(self) -> list[int]:
        """Observations (indices in log order) it takes as outliers."""
        return [i for i, a in enumerate(self.assignment) if a == OUTLIER]

    @property
    def box_size(self) -> float:
        """Sum of all widths: a ranking key (smaller = more informative; inf when a box
        is unbounded or the sum passes the largest double)."""
        with np.errstate(over="ignore", invalid="ignore"):
            widths = np.concatenate(
                [
                    (self.poses[..., 1] - self.poses[..., 0]).ravel(),
                    (self.landmarks[..., 1] - self.landmarks[..., 0]).ravel(),
                ]
            )
            return float(widths.sum())

    @property
    def rank_key(self) -> tuple[bool, int, int, float, float]:
        """How hypotheses are ranked, best first: proven consistent before undecided (an
        undecided one may still be impossible), then fewest outliers (an outlier explains
        nothing), then fewest landmarks (a new landmark explains any observation, so the
        fewest is the most constrained explanation), then the smallest least-squares
        ``fit`` (the readings nearest their intervals' centres; not computed: last), then
        smallest boxes. It is an order, not a probability: every reported hypothesis is
        possible or undecided, and the guarantee holds whichever is true."""
        # fits within 1e-6 tie: a hypothesis whose readings its landmarks absorb costs 0 up
        # to the optimiser's rounding, and rounding must not order it
        fit = round(self.fit, 6) if math.isfinite(self.fit) else math.inf
        return (self.status != PROVEN, len(self.outliers), self.n_landmarks, fit, self.box_size)

    def pose(self, pose_id: int) -> np.ndarray:
        """The (3, 2) box of one pose."""
        return self.poses[self.pose_ids.index(pose_id)]

    def landmark(self, landmark_id: str) -> np.ndarray:
        """The (2, 2) box of one landmark."""
        return self.landmarks[self.landmark_ids.index(landmark_id)]


@dataclass
class Envelope:
    """Unknown correspondence: boxes that hold the truth whenever the log's intervals do,
    whatever the correspondence and whatever stopped the search (see
    :mod:`cuikslam.hypotheses.envelope`)."""

    pose_ids: list[int]
    """Pose ids, increasing."""
    poses: np.ndarray
    """Shape (n_poses, 3, 2): each pose's (x, y, theta) box (headings unwrapped)."""
    observations: np.ndarray
    """Shape (n_observations, 2, 2), in log order: the (x, y) box of the landmark each
    observation sees (unbounded for one that may be an outlier)."""


@dataclass
class Solution:
    """Every surviving hypothesis, best-ranked first, and how the solve went."""

    hypotheses: list[Hypothesis]
    complete: bool = True
    """False when a limit dropped hypotheses: then the true one may be missing."""
    statistics: dict[str, float] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    log_path: str = ""
    consistency: str = ""
    messages: list[str] = field(default_factory=list)
    correspondence: dict | None = None
    """For unknown correspondence: what the reported survivors agree on (JSON-ready; see
    :func:`cuikslam.outcome.summary.summarize` and :func:`.summary.summary_to_json`)."""
    outliers: dict | None = None
    """When the log declares outliers: the declaration and the observations proven to be
    outliers (JSON-ready; see :func:`cuikslam.outliers.outliers_to_json`)."""
    envelope: Envelope | None = None
    """Unknown correspondence: each pose's and each observed landmark's box whatever the
    correspondence, over the survivors and every subtree a budget left unexplored; None
    for known correspondence or a refuted log."""
    unreported: list[list[str]] = field(default_factory=list, repr=False)
    """Unknown correspondence: the assignments of survivors the search found but did not
    report in detail (the first ``MAX_UNREPORTED`` of them; never written to files), from
    which :func:`~cuikslam.witness.fit_hypotheses` reports the best-fitting;
    empty once a search's ``rank`` used it (as in :func:`~cuikslam.solver.solve`)."""

    @property
    def best(self) -> Hypothesis:
        return self.hypotheses[0]

    @property
    def refuted(self) -> bool:
        """True when every hypothesis was proven impossible: the log is inconsistent (not
        when survivors remain that the report did not keep)."""
        unreported = (self.correspondence or {}).get("survivors", 0)
        return not self.hypotheses and self.complete and not unreported


def bounds_to_json(boxes: np.ndarray) -> list:
    """``boxes`` as nested lists of floats; JSON has no infinity: unbounded sides are null."""
    boxes = np.asarray(boxes, dtype=np.float64)
    unbounded = np.isinf(boxes)
    if not unbounded.any():
        return boxes.tolist()
    listed = boxes.astype(object)
    listed[unbounded] = None
    return listed.tolist()


def no_hypothesis(solution: Solution) -> str:
    """Why a result reports no hypothesis, in words (a :class:`~cuikslam.messages.Message`
    when the cure is an option)."""
    if solution.refuted:
        return "the log was refuted"
    if not solution.complete:
        return "the search stopped on its budget before finding one"
    left = (solution.correspondence or {}).get("survivors", 0)
    return Message(
        "unreported_survivors",
        f"{left} survivors were not kept for the report; raise max_hypotheses",
        survivors=left,
    )


@dataclass
class TruthReport:
    """Which boxes miss the truth (an empty ``misses`` means all contain it)."""

    misses: list[str]
    checked: int

    @property
    def ok(self) -> bool:
        return not self.misses


ExactLike = float | int | Fraction | Decimal | str
"""A true value: a float, an exact rational, or a decimal string (all compared exactly)."""


def _exact(value: object) -> Fraction:
    """``value`` as an exact rational: a float exactly, a decimal string or Decimal exactly."""
    if isinstance(value, Fraction):
        return value
    if isinstance(value, np.floating | np.integer):
        value = value.item()
    if isinstance(value, str):
        return Fraction(Decimal(value.strip()))
    if hasattr(value, "man_exp"):  # an mpmath mpf: mantissa * 2**exponent, exactly
        man, exp = value.man_exp
        return Fraction(man) * Fraction(2) ** exp
    return Fraction(value)


def _show(value: object) -> str:
    """A true value in a message: a plain float when it is one, else its decimal digits
    (25 significant at most) marked as such, so that "x=0.1 (decimal)" is not read as the
    float 0.1."""
    exact = _exact(value)
    if Fraction(float(exact)) == exact:
        return repr(float(exact))
    with localcontext() as context:
        context.prec = 25
        digits = Decimal(exact.numerator) / Decimal(exact.denominator)
    return f"{digits} (decimal)"


def check_truth(
    hypothesis: Hypothesis,
    pose_ids: list[int],
    poses_xyt: np.ndarray | Sequence[Sequence[ExactLike]],
    landmark_xy: Mapping[str, Sequence[ExactLike]] | None = None,
) -> TruthReport:
    """Check, exactly, that every box of ``hypothesis`` contains the true poses and landmarks.

    True values may be floats, Fractions, Decimals or decimal strings (e.g.
    :meth:`GroundTruth.exact_poses <cuikslam.simulate.truth.GroundTruth.exact_poses>`):
    each is compared with the float bounds as an exact rational, so a 60-digit truth just
    outside a bound equal to its rounding is a miss. Headings are compared modulo 2π, with
    2π enclosed to 400 digits. ``landmark_xy`` maps the hypothesis' landmark ids to true
    positions (skip landmarks whose identity differs, e.g. in a wrong hypothesis).
    """
    misses: list[str] = []
    checked = 0
    row_of = {p: i for i, p in enumerate(hypothesis.pose_ids)}
    for pose_id, truth in zip(pose_ids, poses_xyt, strict=True):
        if pose_id not in row_of:
            continue
        checked += _check_pose(pose_id, hypothesis.poses[row_of[pose_id]], truth, misses)
    for landmark_id, xy in (landmark_xy or {}).items():
        if landmark_id not in hypothesis.landmark_ids:
            continue
        checked += _check_xy(
            f"landmark {landmark_id}", hypothesis.landmark(landmark_id), xy, misses
        )
    return TruthReport(misses, checked)


def check_envelope(
    envelope: Envelope,
    pose_ids: list[int],
    poses_xyt: Sequence[Sequence[ExactLike]],
    observed_xy: Sequence[Sequence[ExactLike] | None],
) -> TruthReport:
    """Check, exactly, that ``envelope`` holds the true poses (headings modulo 2π) and the
    true landmark each observation sees (``observed_xy``, in log order; None: unchecked)."""
    misses: list[str] = []
    checked = 0
    row_of = {p: i for i, p in enumerate(envelope.pose_ids)}
    for pose_id, truth in zip(pose_ids, poses_xyt, strict=True):
        if pose_id in row_of:
            checked += _check_pose(pose_id, envelope.poses[row_of[pose_id]], truth, misses)
    for i, xy in enumerate(observed_xy):
        if xy is not None and i < len(envelope.observations):
            checked += _check_xy(f"observation {i}", envelope.observations[i], xy, misses)
    return TruthReport(misses, checked)


def _at_most(a: float | Fraction, b: float | Fraction) -> bool:
    """``a <= b`` exactly, where a float may be infinite (an unbounded box)."""
    if isinstance(a, float) and math.isinf(a):
        return a < 0
    if isinstance(b, float) and math.isinf(b):
        return b > 0
    return _exact(a) <= _exact(b)


def _float_inside(bounds: np.ndarray, value: object) -> bool:
    """``lo <= value <= hi`` decided at once when ``value`` is a float or a Fraction
    (Python compares them with a float exactly); False otherwise or when it lies
    outside (then the exact test decides, e.g. modulo 2π for an angle)."""
    if isinstance(value, np.floating):
        value = value.item()
    if type(value) not in (float, Fraction):
        return False
    return float(bounds[0]) <= value <= float(bounds[1])


def _check_pose(pose_id: int, box: np.ndarray, xyt: Sequence[ExactLike], misses: list[str]) -> int:
    """Append a line to ``misses`` for each of x, y, theta (modulo 2π) outside the pose box
    ``box``; return 3 (bounds checked)."""
    _check_xy(f"pose {pose_id}", box, xyt, misses)
    if not (_float_inside(box[2], xyt[2]) or angle_in(*box[2], _exact(xyt[2]))):
        misses.append(f"pose {pose_id} theta={_show(xyt[2])} not in {box[2].tolist()} (mod 2pi)")
    return 3


def _check_xy(label: str, box: np.ndarray, xy: Sequence[ExactLike], misses: list[str]) -> int:
    """Append a line to ``misses`` for each of x, y outside its box; return 2 (bounds checked)."""
    for j, name in enumerate(("x", "y")):
        if _float_inside(box[j], xy[j]):
            continue
        lo, hi = float(box[j, 0]), float(box[j, 1])
        value = _exact(xy[j])
        if not (lo <= hi and _at_most(lo, value) and _at_most(value, hi)):
            misses.append(f"{label} {name}={_show(xy[j])} not in {box[j].tolist()}")
    return 2
