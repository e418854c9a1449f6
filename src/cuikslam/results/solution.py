"""What a solve returns: re-exported from :mod:`cuikslam.outcome.solution`, its home below
the search (this module stays importable for existing code and pickled results)."""

from cuikslam.outcome import solution as _home
from cuikslam.outcome.solution import *  # noqa: F403 (every public name of its home)

__all__ = list(_home.__all__)
