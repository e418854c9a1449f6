"""Whether a truth file is the truth of the log (or result) it is given with.

:func:`check_truth_fits` refuses a truth that assigns another number of observations, has
poses the log does not have, or lacks a landmark the log names (it may lack poses: Vicon
gaps); :func:`truth_misfit` says what does not fit (a :class:`TruthMisfit`). The truth is
read by :func:`cuikslam.simulate.truth.read_truth_file` (which imports these names too).
"""

from __future__ import annotations

import os
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from cuikslam.errors import InputFileError
from cuikslam.log.records import Log

if TYPE_CHECKING:
    from cuikslam.outcome.solution import Solution
    from cuikslam.simulate.truth import GroundTruth

__all__ = ["TruthMisfit", "TruthMismatchError", "check_truth_fits", "truth_misfit"]


@dataclass(frozen=True)
class TruthMisfit:
    """How a truth does not fit the log (or the result of a log) it is given with.

    Attributes
    ----------
    assigned : int
        Observations the truth assigns a landmark to.
    observations : int
        Observations of the log.
    count_differs : bool
        True when ``assigned`` is not ``observations`` (and has to be).
    extra_poses : tuple of int
        Pose ids of the truth that the log does not have, sorted.
    missing_landmarks : tuple of str
        Landmark ids the log names that the truth does not have, sorted.
    """

    assigned: int
    observations: int
    count_differs: bool = False
    extra_poses: tuple[int, ...] = ()
    missing_landmarks: tuple[str, ...] = ()

    def __bool__(self) -> bool:
        return self.count_differs or bool(self.extra_poses or self.missing_landmarks)

    def describe(self, other: str = "the log") -> str:
        """What does not fit, in one line (``other`` names what the truth is held against).

        Examples
        --------
        >>> TruthMisfit(210, 33, count_differs=True).describe()
        'it assigns 210 observations, the log has 33'
        >>> TruthMisfit(33, 33, extra_poses=tuple(range(6, 30))).describe("the result")
        'it has 24 poses the result lacks (6, 7, 8, …, 29)'
        """
        parts = []
        if self.count_differs:
            parts.append(
                f"it assigns {_count(self.assigned, 'observation')}, {other} has "
                f"{self.observations}"
            )
        if self.extra_poses:
            parts.append(
                f"it has {_count(len(self.extra_poses), 'pose')} {other} lacks "
                f"({_listing(self.extra_poses)})"
            )
        if self.missing_landmarks:
            parts.append(
                f"{other} names {_count(len(self.missing_landmarks), 'landmark')} it lacks "
                f"({_listing(self.missing_landmarks)})"
            )
        return "; ".join(parts)


class TruthMismatchError(InputFileError):
    """A truth file that does not fit the log (or result) it is given with.

    Attributes
    ----------
    path : str
        The truth file.
    other_path : str
        The log (or result) it does not fit.
    misfit : TruthMisfit
        What does not fit.
    """

    def __init__(
        self,
        truth_path: str | os.PathLike[str],
        other_path: str | os.PathLike[str],
        misfit: TruthMisfit,
        other: str = "the log",
    ) -> None:
        super().__init__(truth_path, None, misfit.describe(other))
        self.other_path = os.fspath(other_path)
        self.misfit = misfit

    def __str__(self) -> str:
        return f"{self.path} does not fit {self.other_path}: {self.problem}"


def truth_misfit(
    truth: GroundTruth,
    pose_ids: Collection[int],
    observations: int,
    named: Collection[str] = (),
    *,
    assignment_optional: bool = False,
) -> TruthMisfit:
    """How ``truth`` does not fit a log with these poses, observations and named landmarks.

    A truth fits when it assigns a landmark to every observation (or, with
    ``assignment_optional``, to none), every pose it has is a pose of the log (it may lack
    some: Vicon gaps), and it has every landmark the log names.

    Parameters
    ----------
    truth : GroundTruth
        The truth read from a file.
    pose_ids : collection of int
        The log's pose ids.
    observations : int
        The log's number of observations.
    named : collection of str
        Landmark ids the log names (sightings and landmark priors).
    assignment_optional : bool
        Accept a truth without assignment (``cuikslam evaluate`` then matches landmarks
        by id).

    Returns
    -------
    TruthMisfit
        False (as a bool) when the truth fits.
    """
    assigned = len(truth.assignment)
    skipped = assignment_optional and assigned == 0
    poses, landmarks = set(pose_ids), set(truth.landmark_ids)
    return TruthMisfit(
        assigned=assigned,
        observations=observations,
        count_differs=assigned != observations and not skipped,
        extra_poses=tuple(sorted(p for p in set(truth.pose_ids) if p not in poses)),
        missing_landmarks=tuple(sorted(m for m in set(named) if m not in landmarks)),
    )


def check_truth_fits(
    truth: GroundTruth,
    truth_path: str | os.PathLike[str],
    against: Log | Solution,
    against_path: str | os.PathLike[str] | None = None,
    *,
    assignment_optional: bool = False,
) -> None:
    """Refuse a truth file that is not the truth of the log it is given with.

    Parameters
    ----------
    truth : GroundTruth
        What :func:`~cuikslam.simulate.truth.read_truth_file` read from ``truth_path``.
    truth_path : str or PathLike
        The truth file, for the message.
    against : Log or Solution
        The log; or, when the log is not at hand, a result of it (its best hypothesis, or
        without one its envelope, gives the poses and observations; the landmarks the log
        names are then unknown).
    against_path : str or PathLike, optional
        The file ``against`` was read from (default: the log's ``path``; give the result's).
    assignment_optional : bool
        Accept a truth without assignment (see :func:`truth_misfit`).

    Raises
    ------
    TruthMismatchError
        Naming both files and what does not fit (see :class:`TruthMisfit`).
    """
    if isinstance(against, Log):
        named = {m for r in against.records if (m := getattr(r, "landmark", None)) is not None}
        facts, other = (against.pose_ids, len(against.observations), named), "the log"
    elif against.hypotheses:
        best = against.best
        facts, other = (best.pose_ids, len(best.assignment)), "the result"
    else:  # a search stopped before its first hypothesis: its envelope has the same facts
        envelope = against.envelope
        assert envelope is not None, "a result with neither hypothesis nor envelope"
        facts, other = (envelope.pose_ids, len(envelope.observations)), "the result"
    misfit = truth_misfit(truth, *facts, assignment_optional=assignment_optional)
    if misfit:
        name = against_path if against_path is not None else getattr(against, "path", other)
        raise TruthMismatchError(truth_path, name, misfit, other)


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" if n == 1 else f"{n} {noun}s"


def _listing(values: Sequence[object], shown: int = 5) -> str:
    """``values`` joined with commas; beyond ``shown``, the first three, an ellipsis, the last."""
    if len(values) <= shown:
        return ", ".join(map(str, values))
    return ", ".join([*map(str, values[:3]), "…", str(values[-1])])
