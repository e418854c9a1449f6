"""Shared test setup: every test starts and ends in round-to-nearest mode.

codac (IBEX/gaol), a test-only dependency, switches the process to rounding upward at
its first use and leaves it so; without this, tests that run after a codac test would
see a different floating-point world (even ``repr`` of floats changes).
"""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Iterator

import pytest

import cuikslam
from cuikslam._fpu import ensure_round_to_nearest


@pytest.fixture(autouse=True)
def _round_to_nearest() -> Iterator[None]:
    ensure_round_to_nearest()
    yield
    ensure_round_to_nearest()


def pytest_collectstart(collector: pytest.Collector) -> None:
    """Import every test module in round-to-nearest mode.

    ``import codac`` alone switches the process to rounding upward; a test module imported
    after that would parse its float literals in that mode (``-0.3927`` would become
    ``-0.39270000000000005``).
    """
    ensure_round_to_nearest()


def pytest_configure(config: pytest.Config) -> None:
    """Import every module of cuikslam before the first test.

    Hypothesis draws some of its numbers from the constants written in the local modules
    imported so far (its "local constants", read again whenever ``sys.modules`` grows).
    Without this, a derandomized property test would draw other worlds, at another cost,
    depending on which tests ran before it and imported what: run alone it would not check
    the worlds (nor take the time) it does in the whole run. (Helper modules outside the
    package that a test imports, ``benchmarks/jcbb.py`` and ``build_backend/``, still add
    their few constants when imported: strings, and one float, 900.0.)
    """
    _compile_before_workers(config)
    for module in pkgutil.walk_packages(cuikslam.__path__, "cuikslam."):
        try:
            importlib.import_module(module.name)
        except ImportError as missing:  # an optional dependency: that module stays out
            if (missing.name or "").startswith("cuikslam"):
                raise
    ensure_round_to_nearest()


def _compile_before_workers(config: pytest.Config) -> None:
    """With pytest-xdist's workers (``-n``), compile every kernel into numba's cache here,
    in the controller, before they start: two workers compiling one generalized ufunc at
    once can crash the one that then loads it from the cache (numba issue 10128; a CI run
    lost two workers in ``test_interval_backward.py`` that way). A warm cache loads in
    seconds."""
    workers = getattr(config.option, "numprocesses", None)
    if not workers or hasattr(config, "workerinput"):
        return
    from cuikslam.cli.warm_up import PARTS, warm_part

    for part in PARTS:
        warm_part(part)
