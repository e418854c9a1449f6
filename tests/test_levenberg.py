"""The bounded Levenberg-Marquardt least squares behind the witness search and the fit."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from cuikslam.witness._levenberg import bounded_least_squares


class _Counted:
    """Residuals and Jacobian of a function, recording every point evaluated."""

    def __init__(self, f) -> None:
        self.f = f
        self.points: list[np.ndarray] = []

    def __call__(self, z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        self.points.append(z.copy())
        return self.f(z)


@pytest.mark.parametrize("seed", range(5))
def test_a_bounded_linear_problem_reaches_its_unique_minimum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(40, 12))
    b = rng.normal(size=40) * 3.0
    lb, ub = -0.5 * np.ones(12), 0.5 * np.ones(12)
    expected = lsq_linear(A, b, bounds=(lb, ub), tol=1e-14).x
    assert np.any(np.isclose(np.abs(expected), 0.5))  # some bounds are active
    z = bounded_least_squares(lambda z: (A @ z - b, A), np.zeros(12), lb, ub, 200, 1e-14)
    np.testing.assert_allclose(z, expected, atol=1e-9)


def test_a_curved_valley_is_followed_to_its_minimum() -> None:
    def rosenbrock(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = np.array([10.0 * (z[1] - z[0] ** 2), 1.0 - z[0]])
        return r, np.array([[-20.0 * z[0], 10.0], [-1.0, 0.0]])

    lb, ub = np.array([-2.0, -2.0]), np.array([2.0, 2.0])
    z = bounded_least_squares(rosenbrock, np.array([-1.2, 1.0]), lb, ub, 100, 1e-14)
    np.testing.assert_allclose(z, [1.0, 1.0], atol=1e-10)


def test_every_point_evaluated_is_inside_the_bounds_and_the_budget_holds() -> None:
    rng = np.random.default_rng(7)
    A = rng.normal(size=(30, 10))
    b = rng.normal(size=30) * 10.0
    lb, ub = -np.ones(10), np.ones(10)
    f = _Counted(lambda z: (np.sin(A @ z) * 5.0 - b, np.cos(A @ z)[:, None] * 5.0 * A))
    bounded_least_squares(f, rng.uniform(-1, 1, 10), lb, ub, 7, 1e-14)
    assert 1 < len(f.points) <= 7
    assert all(np.all((p >= lb) & (p <= ub)) for p in f.points)


def test_a_non_finite_model_ends_the_search_at_a_point_inside_the_bounds() -> None:
    f = _Counted(lambda z: (np.array([1e200 * (z[0] + 2.0)]), np.array([[np.inf]])))
    z = bounded_least_squares(f, np.array([0.5]), np.array([-1.0]), np.array([1.0]), 50, 1e-14)
    assert -1.0 <= z[0] <= 1.0
    assert len(f.points) <= 50
