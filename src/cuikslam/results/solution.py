"""What a solve returns: re-exported from :mod:`cuikslam.outcome.solution`, its home below
the search (this module stays importable for existing code and pickled results)."""

from cuikslam.outcome.solution import (
    NOT_REFUTED,
    OUTLIER,
    PROVEN,
    Envelope,
    ExactLike,
    Hypothesis,
    Solution,
    TruthReport,
    bounds_to_json,
    check_envelope,
    check_truth,
    no_hypothesis,
)

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
