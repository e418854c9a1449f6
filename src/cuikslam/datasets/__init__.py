"""Importers for real robot datasets, and where to find them.

``DATA_DIR`` is the folder holding the datasets: the environment variable
``CUIKSLAM_DATA`` when set, else ``../shared/data`` beside the repository when it
exists, else ``None``.
"""

from __future__ import annotations

import os
from pathlib import Path

from cuikslam.datasets.lost_in_the_woods import read_lost_in_the_woods

__all__ = ["DATA_DIR", "data_dir", "read_lost_in_the_woods"]


def data_dir() -> Path | None:
    """The dataset folder (see the module docstring), resolved now."""
    env = os.environ.get("CUIKSLAM_DATA")
    if env:
        return Path(env)
    # parents: [0] datasets, [1] cuikslam, [2] src, [3] the repository root.
    parents = Path(__file__).resolve().parents
    if len(parents) > 3:
        candidate = parents[3].parent / "shared" / "data"
        if candidate.is_dir():
            return candidate
    return None


DATA_DIR: Path | None = data_dir()
