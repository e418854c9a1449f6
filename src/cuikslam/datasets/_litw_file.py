"""Reading ``dataset2.mat`` of Lost in the Woods: its variables, checked, or one clear error."""

from __future__ import annotations

import os

import numpy as np

from cuikslam.errors import InputFileError

__all__ = ["load_dataset"]

VARIABLES = (
    "t", "v", "om", "r", "b", "l", "x_true", "y_true", "th_true", "true_valid", "d",
    "v_var", "om_var",
)  # fmt: skip


def load_dataset(path: str | os.PathLike[str]) -> dict[str, np.ndarray]:
    """The variables of ``dataset2.mat`` (``VARIABLES``, as SciPy reads them).

    Raises
    ------
    InputFileError
        If the file is missing, not a MATLAB file, or lacks a variable.
    """
    import scipy.io

    try:
        data = scipy.io.loadmat(os.fspath(path))
    except FileNotFoundError:
        raise InputFileError(path, None, "no such file (expected dataset2.mat)") from None
    except Exception as exc:  # scipy raises several types for a non-MAT file
        raise InputFileError(path, None, f"cannot read MATLAB file: {exc}") from None
    missing = [name for name in VARIABLES if name not in data]
    if missing:
        raise InputFileError(
            path, None, f"not a Lost-in-the-Woods file: lacks variable(s) {', '.join(missing)}"
        )
    return data
