"""Shared test setup: every test starts and ends in round-to-nearest mode.

codac (IBEX/gaol), a test-only dependency, switches the process to rounding upward at
its first use and leaves it so; without this, tests that run after a codac test would
see a different floating-point world (even ``repr`` of floats changes).
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

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
