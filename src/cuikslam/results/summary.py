"""The correspondence summary: re-exported from :mod:`cuikslam.outcome.summary`, its home
below the search (this module stays importable for existing code)."""

from cuikslam.outcome.summary import (
    NEW,
    Ambiguity,
    CorrespondenceSummary,
    ambiguous_observations,
    describe,
    summarize,
    summary_from_json,
    summary_holds,
    summary_to_json,
)

__all__ = [
    "NEW",
    "Ambiguity",
    "CorrespondenceSummary",
    "ambiguous_observations",
    "describe",
    "summarize",
    "summary_from_json",
    "summary_holds",
    "summary_to_json",
]
