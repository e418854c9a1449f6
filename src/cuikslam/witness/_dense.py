"""Least squares on the model's own parameters, whose Jacobian is dense: the fit's.

:mod:`.fit` minimises :meth:`~.model.HypothesisModel.fit_residuals` over the motions'
parameters (every pose depends on every step before it, so the Jacobian is dense).
The witness search minimises its hinges in the sparse world form instead
(:mod:`._world`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from cuikslam.budget import COSTS
from cuikslam.witness._levenberg import bounded_least_squares
from cuikslam.witness._numeric import finite
from cuikslam.witness.model import HypothesisModel, aim_margin

TR_SOLVER = "normal"
"""Solver of the least squares on the model's dense Jacobians up to ``LSMR_ABOVE`` free
parameters: :func:`~._levenberg.bounded_least_squares` (Cholesky of the normal equations).
scipy's ``trf`` with an SVD per step (``"exact"``, used before) certified a 200-pose world
in 23 s against 4.7 s."""
LSMR_ABOVE = 500
"""Beyond this many free parameters the least squares use scipy's iterative ``lsmr``
instead (no factorisation): on the 201-pose Lost in the Woods window (1,237 parameters)
the SVD took 0.45 s a step, and the best-ranked survivor was proven in 2.6 s instead of
6.6 s."""


def tr_solver_for(n_free: int) -> str:
    """The trust-region solver for a least squares of ``n_free`` parameters.

    >>> tr_solver_for(200), tr_solver_for(1237)
    ('normal', 'lsmr')
    """
    return TR_SOLVER if n_free <= LSMR_ABOVE else "lsmr"


def param_bounds(model: HypothesisModel) -> tuple[np.ndarray, np.ndarray]:
    """The parameters' intervals, each narrowed by its aimed margin."""
    margin = aim_margin(model.param_lo, model.param_hi)
    lb = np.where(np.isfinite(model.param_lo), model.param_lo + margin, -np.inf)
    ub = np.where(np.isfinite(model.param_hi), model.param_hi - margin, np.inf)
    return lb, ub


def dense_least_squares(
    residuals: Any,
    z0: np.ndarray,
    tick: Callable[[], None],
    max_nfev: int,
    columns: np.ndarray,
    bounds: tuple[np.ndarray, np.ndarray],
    tr_solver: str = TR_SOLVER,
    tol: float = 1e-14,
    spend: Callable[[float], None] | None = None,
) -> np.ndarray:
    """Least squares on ``residuals(z, jacobian=True)`` (the Jacobian's columns ``columns``)
    within ``bounds``, ``tick()`` called at every evaluation (it may stop the search by
    raising); ``tr_solver`` is ``"normal"`` (:func:`~._levenberg.bounded_least_squares`)
    or scipy's trust-region solver, ``tol`` the tolerances (cost, step, gradient).

    With ``"lsmr"``, each product by the Jacobian or its transpose is passed to ``spend``
    as work units (:data:`~cuikslam.budget.COSTS` ``product_entry`` per entry; it may
    raise too): a step's ``lsmr`` makes up to one pair per parameter, and on a 1,000-pose
    log (2,101 parameters, 12,667 rows) each pair takes 20 ms, so an evaluation's work
    grows with the Jacobian's size times its iterations, not with the residuals."""
    memo: dict[bytes, tuple[np.ndarray, Any]] = {}
    all_columns = bool(np.all(columns))

    def both(z: np.ndarray) -> tuple[np.ndarray, Any]:
        key = z.tobytes()
        if key not in memo:
            tick()
            memo.clear()
            r, J = residuals(z, jacobian=True)
            memo[key] = (finite(r), finite(J if all_columns else J[:, columns], nan=0.0))
        return memo[key]

    if tr_solver == "normal":
        return bounded_least_squares(both, z0, bounds[0], bounds[1], max_nfev, tol)
    from scipy.optimize import least_squares  # loaded when a fit is computed

    def jac(z: np.ndarray) -> Any:
        J = both(z)[1]
        return J if spend is None or tr_solver != "lsmr" else _counted(J, spend)

    with np.errstate(all="ignore"):  # huge magnitudes overflow its steps: no fit, no warning
        result = least_squares(
            lambda z: both(z)[0], z0, jac=jac,
            bounds=bounds,
            method="trf", xtol=tol, ftol=tol, gtol=tol, max_nfev=max_nfev,
            tr_solver=tr_solver,
        )  # fmt: skip
    return result.x


def _counted(J: np.ndarray, spend: Callable[[float], None]) -> Any:
    """``J`` as a linear operator whose every product spends its work first."""
    from scipy.sparse.linalg import LinearOperator

    units = COSTS["product_entry"] * J.size

    def matvec(v: np.ndarray) -> np.ndarray:
        spend(units)
        return J @ v

    def rmatvec(u: np.ndarray) -> np.ndarray:
        spend(units)
        return J.T @ u

    def matmat(V: np.ndarray) -> np.ndarray:
        spend(units * V.shape[1])
        return J @ V

    def rmatmat(U: np.ndarray) -> np.ndarray:
        spend(units * U.shape[1])
        return J.T @ U

    return LinearOperator(
        J.shape, matvec=matvec, rmatvec=rmatvec, matmat=matmat, rmatmat=rmatmat, dtype=J.dtype
    )


def evaluation_cost(model: HypothesisModel) -> float:
    """Work units of one evaluation of ``model``'s residuals and Jacobian: a fixed cost, and
    one per parameter and per check, so that the work does not depend on the machine."""
    return COSTS["evaluation"] + COSTS["residual"] * (model.n_params + model.n_checks)
