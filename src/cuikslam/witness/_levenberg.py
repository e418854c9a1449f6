"""A bounded Levenberg-Marquardt least squares on the normal equations.

The witness search and the fit minimise residuals whose Jacobian is dense: a pose depends
on every move before it. scipy's ``trf`` solves each trust-region step with an SVD of the
whole Jacobian; on a 200-pose world (about 600 residuals, 430 parameters) that took 68 ms
a step, most of a 23 s certification. Factoring the normal equations takes a few
milliseconds, so the steps here solve ``(J^T J + lam D) step = -J^T r`` by Cholesky, with
Marquardt's scaling ``D`` (the largest diagonal of ``J^T J`` seen so far) and Nielsen's
update of ``lam``. Bounds are kept by projecting each step onto them; a parameter at a
bound that the gradient pushes outwards is held there for the step.

These optimisers only *propose* points: whether a point is a witness is decided in interval
arithmetic (:mod:`.verify`), so a poor step costs time, never soundness.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sp
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.sparse.linalg import SuperLU, splu

ResidualsAndJacobian = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]

_ACCEPT = 1e-4
"""A step is taken when it achieves this share of the decrease its linear model predicts."""
_SPLU = {
    "permc_spec": "MMD_AT_PLUS_A",
    "diag_pivot_thresh": 0.0,
    "options": {"SymmetricMode": True},
}
"""SuperLU on a symmetric positive definite matrix: a symmetric ordering and diagonal
pivots, so it factorises like a sparse Cholesky (with the default partial pivoting, the
fill of a 1,000-pose world's normal equations, and the time, grew sevenfold)."""
_LAM_START = 1e-3
_LAM_LIMITS = (1e-15, 1e15)
"""Beyond the upper limit no step of the model decreases the cost: the search ends."""


@np.errstate(over="ignore", invalid="ignore")  # huge residuals only make steps rejected
def bounded_least_squares(
    residuals: ResidualsAndJacobian,
    z0: np.ndarray,
    lb: np.ndarray,
    ub: np.ndarray,
    max_nfev: int,
    tol: float,
    factorised: Callable[[float], None] | None = None,
    ordering: np.ndarray | None = None,
) -> np.ndarray:
    """A local minimiser of ``|r(z)|^2`` with ``lb <= z <= ub``, from ``z0``.

    ``residuals(z)`` returns ``(r, J)`` (finite; ``J`` dense or sparse). Stops after
    ``max_nfev`` evaluations, or when a taken step changes the cost by less than ``tol`` of
    it or moves ``z`` by less than ``tol`` of its norm, or when the gradient of the free
    parameters is below ``tol``. ``factorised`` is told the multiply-adds of each sparse
    factorisation (:func:`factor_work`), whose cost grows faster than the matrix;
    ``ordering`` is the order in which they eliminate the parameters
    (:func:`fill_reducing_order`; default: SuperLU's, computed anew each time).

    A minimum at (3, -1), the second coordinate held at its lower bound 0:

    >>> f = lambda z: (np.array([z[0] - 3.0, 2.0 * (z[1] + 1.0)]), np.diag([1.0, 2.0]))
    >>> lb, ub = np.array([-5.0, 0.0]), np.array([5.0, 5.0])
    >>> bounded_least_squares(f, np.zeros(2), lb, ub, max_nfev=50, tol=1e-12)
    array([3., 0.])
    """
    z = np.clip(np.asarray(z0, dtype=float), lb, ub)
    r, J = residuals(z)
    nfev = 1
    cost = 0.5 * float(r @ r)
    g, H = J.T @ r, _normal(J)
    scale = H.diagonal().copy()
    lam, nu = _LAM_START, 2.0
    while nfev < max_nfev:
        free = ~(((z <= lb) & (g > 0)) | ((z >= ub) & (g < 0)))
        if not np.any(free) or np.max(np.abs(g[free])) <= tol:
            return z
        scale = np.maximum(scale, H.diagonal())
        floor = 1e-12 * float(scale.max()) if scale.max() > 0 else 1.0
        d = np.maximum(scale[free], floor)
        h_free, g_free = _restrict(H, free), g[free]
        while True:
            if not lam < _LAM_LIMITS[1]:
                return z
            order = None if ordering is None else _suborder(ordering, free)
            step = _damped_step(h_free, g_free, lam * d, factorised, order)
            if step is None:
                lam, nu = lam * nu, nu * 2.0
                continue
            trial = z.copy()
            trial[free] += step
            trial = np.clip(trial, lb, ub)
            s = trial - z
            if not np.any(s):
                return z
            js = J @ s
            predicted = -(float(g @ s) + 0.5 * float(js @ js))
            r_t, J_t = residuals(trial)
            nfev += 1
            cost_t = 0.5 * float(r_t @ r_t)
            decrease = cost - cost_t
            if predicted > 0 and decrease > _ACCEPT * predicted:
                rho = decrease / predicted
                small_step = np.linalg.norm(s) < tol * (tol + np.linalg.norm(z))
                z, r, J, cost = trial, r_t, J_t, cost_t
                g, H = J.T @ r, _normal(J)
                lam = max(lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), _LAM_LIMITS[0])
                nu = 2.0
                if small_step or (decrease < tol * (cost + decrease) and rho > 0.25):
                    return z
                break
            lam, nu = lam * nu, nu * 2.0
            if nfev >= max_nfev:
                return z
    return z


def _normal(J: np.ndarray | sp.spmatrix) -> np.ndarray | sp.csc_matrix:
    """``J^T J``: dense for a dense ``J``, sparse (CSC) for a sparse one."""
    if sp.issparse(J):
        return sp.csc_matrix(J.T @ J)
    return J.T @ J


def _restrict(H: np.ndarray | sp.csc_matrix, free: np.ndarray) -> np.ndarray | sp.csc_matrix:
    """The rows and columns ``free`` of ``H``."""
    if bool(np.all(free)):
        return H
    if sp.issparse(H):
        return H[free][:, free]
    return H[np.ix_(free, free)]


def _suborder(ordering: np.ndarray, free: np.ndarray) -> np.ndarray:
    """``ordering`` (of all parameters) restricted to the ``free`` ones, renumbered."""
    if bool(np.all(free)):
        return ordering
    position = np.cumsum(free) - 1
    return position[ordering[free[ordering]]]


def _damped_step(
    h: np.ndarray | sp.csc_matrix,
    g: np.ndarray,
    damping: np.ndarray,
    factorised: Callable[[float], None] | None = None,
    order: np.ndarray | None = None,
) -> np.ndarray | None:
    """The solution of ``(h + diag(damping)) step = -g``, or None when it cannot be had
    (Cholesky for a dense ``h``; for a sparse one a sparse LU, eliminating in ``order``
    when given, whose multiply-adds ``factorised`` is told)."""
    if sp.issparse(h):
        a = sp.csc_matrix(h + sp.diags(damping))
        if not np.all(np.isfinite(a.data)):
            return None
        options = _SPLU
        if order is not None:
            a, options = sp.csc_matrix(a[order][:, order]), {**_SPLU, "permc_spec": "NATURAL"}
        try:
            lu = splu(a, **options)
        except RuntimeError:  # singular
            return None
        if factorised is not None:
            factorised(factor_work(lu))
        if order is None:
            step = -lu.solve(g)
        else:
            step = np.empty_like(g)
            step[order] = -lu.solve(g[order])
        return step if np.all(np.isfinite(step)) else None
    a = h + np.diag(damping)
    if not np.all(np.isfinite(a)):
        return None
    try:
        step = -cho_solve(cho_factor(a, check_finite=False), g, check_finite=False)
    except LinAlgError:
        return None
    return step if np.all(np.isfinite(step)) else None


def factor_work(lu: SuperLU) -> float:
    """Multiply-adds of a sparse LU factorisation, counted as the entries of each
    pivot's column of ``L`` times those of its row of ``U`` (diagonal included).

    >>> a = sp.csc_matrix(np.array([[4.0, 1.0, 0.0], [1.0, 4.0, 1.0], [0.0, 1.0, 4.0]]))
    >>> factor_work(splu(a, **_SPLU))  # pivots of 2 x 2, 2 x 2 and 1 x 1 entries
    9.0
    """
    below = np.diff(sp.csc_matrix(lu.L).indptr).astype(float)
    right = np.diff(sp.csr_matrix(lu.U).indptr).astype(float)
    return float(below @ right)


def fill_reducing_order(pattern: sp.spmatrix) -> tuple[np.ndarray, float]:
    """An order of elimination for symmetric matrices whose entries lie within the pattern
    of ``pattern`` (square, symmetric): SuperLU's minimum degree ordering, computed once
    (on a log whose landmarks are each seen thousands of times, computing it took 15 times
    as long as the factorisation it orders); and the multiply-adds of factorising in it.

    >>> path = sp.diags([np.ones(3), np.ones(4), np.ones(3)], [-1, 0, 1])
    >>> order, work = fill_reducing_order(path)
    >>> sorted(order.tolist()), work  # no fill: pivots of 2 x 2 entries, the last 1 x 1
    ([0, 1, 2, 3], 13.0)
    """
    n = pattern.shape[0]
    ones = sp.csc_matrix((np.ones(pattern.nnz), pattern.nonzero()), shape=pattern.shape)
    lu = splu(sp.csc_matrix(abs(ones) + sp.identity(n) * (n + 1.0)), **_SPLU)
    return np.argsort(lu.perm_c), factor_work(lu)
