"""Unknown correspondence: a collection of kinematic graphs, one per correspondence hypothesis."""

from cuikslam.hypotheses.search import DEFAULT_MAX_HYPOTHESES, solve_unknown
from cuikslam.hypotheses.tree import SearchStatistics

__all__ = ["DEFAULT_MAX_HYPOTHESES", "SearchStatistics", "solve_unknown"]
