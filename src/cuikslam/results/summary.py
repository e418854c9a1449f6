"""The correspondence summary: re-exported from :mod:`cuikslam.outcome.summary`, its home
below the search (this module stays importable for existing code)."""

from cuikslam.outcome import summary as _home
from cuikslam.outcome.summary import *  # noqa: F403 (every public name of its home)

__all__ = list(_home.__all__)
