"""The exception the log layer raises for bad input (see :mod:`cuikslam.errors`)."""

from __future__ import annotations

from cuikslam.errors import InputFileError, LogFormatError

__all__ = ["InputFileError", "LogFormatError"]
