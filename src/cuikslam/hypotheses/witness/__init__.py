"""The certification's former home: it is :mod:`cuikslam.witness` (it certifies
known-correspondence solves too, so it is no part of the search).

This package stays importable for existing code: its names are those of
:mod:`cuikslam.witness`, and its public modules (``cuikslam.hypotheses.witness.fit``, ...)
are the same module objects as the new ones (so a patch through either reaches both).
"""

import importlib
import sys

from cuikslam import witness as _home
from cuikslam.witness import *  # noqa: F403 (every public name of its home)

__all__ = list(_home.__all__)

MODULES = ("certification", "find", "fit", "hull", "model", "verify")
"""The public modules of :mod:`cuikslam.witness` importable under this package's name."""

for _name in MODULES:
    sys.modules[f"{__name__}.{_name}"] = importlib.import_module(f"cuikslam.witness.{_name}")
