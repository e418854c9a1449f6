"""Unknown correspondence: a collection of kinematic graphs, one per correspondence hypothesis."""

from cuikslam.hypotheses.explorer import SearchStatistics
from cuikslam.hypotheses.search import DEFAULT_MAX_HYPOTHESES, solve_unknown

__all__ = ["DEFAULT_MAX_HYPOTHESES", "SearchStatistics", "solve_unknown"]
