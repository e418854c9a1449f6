"""cuikslam's build backend: setuptools', plus the compiled kernels in the wheel.

``pyproject.toml`` names this module as the backend (``backend-path``). It is
``setuptools.build_meta`` with two changes:

* a wheel's build environment also gets what compiling the kernels imports (NumPy, numba,
  SciPy, highspy, at ``[project]``'s lower bounds); an sdist's or an editable install's
  does not;
* :class:`BuildPy` (``[tool.setuptools.cmdclass]``), after copying the modules to the
  build directory, compiles the kernels there (:mod:`cuikslam_kernel_cache`), so that the wheel,
  and the ``site-packages`` that ``pip install .`` fills from it, hold numba's cache.

``CUIKSLAM_BUILD_KERNEL_CACHE=0`` turns both off. A failed compilation never fails the
build: the wheel is then built without the cache, as before.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from setuptools import build_meta as _setuptools
from setuptools.build_meta import *  # noqa: F403  (the PEP 517 hooks not changed here)
from setuptools.command.build_py import build_py as _build_py

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cuikslam_kernel_cache as kernel_cache


def get_requires_for_build_wheel(config_settings: dict | None = None) -> list[str]:
    """setuptools' requirements, and those of compiling the kernels (PEP 517 hook)."""
    pyproject = Path.cwd() / "pyproject.toml"
    extra = kernel_cache.kernel_requirements(pyproject, os.environ)
    return [*_setuptools.get_requires_for_build_wheel(config_settings), *extra]


def get_requires_for_build_editable(config_settings: dict | None = None) -> list[str]:
    """setuptools' own requirements: an editable install compiles nothing (PEP 660 hook)."""
    return _setuptools.get_requires_for_build_editable(config_settings)


def _say(message: str) -> None:
    """A line in the build's log (``pip install -v`` shows it)."""
    print(f"cuikslam: {message}", flush=True)


class BuildPy(_build_py):
    """``build_py`` that also compiles the kernels in the build directory (not editable)."""

    def run(self) -> None:
        """Copy the modules, then compile the kernels beside the copies."""
        super().run()
        wanted, why_not = kernel_cache.should_compile(
            bool(getattr(self, "editable_mode", False)), os.environ
        )
        if not wanted:
            _say(f"kernels not compiled: {why_not}")
            return
        _say("compiling the kernels into the wheel (about 25 s)")
        ok, message = kernel_cache.compile_kernels(Path(self.build_lib), os.environ)
        if ok:
            _say(message)
        else:
            self.warn(f"cuikslam: {message}")

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        """The modules' copies, and the cache files compiled beside them."""
        cached = [str(p) for p in kernel_cache.cache_files(Path(self.build_lib))]
        return [*super().get_outputs(include_bytecode), *cached]
