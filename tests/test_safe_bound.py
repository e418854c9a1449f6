"""The Neumaier–Shcherbina safe bound holds for *any* multipliers: garbage in, a valid bound out.

``safe_lower_bound`` re-derives each LP bound from the LP's row multipliers in interval
arithmetic, so that a wrong LP answer can only weaken a bound. These tests feed it
random, wrong-sign, huge, tiny, zero, infinite and NaN multipliers, on polytopes that
contain a known point ``x0`` *exactly* (row bounds are rounded outward around ``A x0``,
checked in rational arithmetic), and check in rational arithmetic that the bound never
exceeds ``c x0``. With a degenerate box ``[x0, x0]`` the true minimum *is* ``c x0``, so a
bound rounded the wrong way by a single ulp fails.
"""

from __future__ import annotations

import math
from fractions import Fraction

import highspy
import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from scipy import sparse

from cuikslam.graph import KinematicGraph
from cuikslam.narrowing import lp_bounds, propagate
from cuikslam.narrowing.lp_bounds import WarmStarts, _model, certified_bounds
from cuikslam.narrowing.relaxation import relax
from cuikslam.narrowing.safe_bound import safe_lower_bound
from cuikslam.simulate import simulate_random_world

garbage = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 1e300, -1e300, 1.0, -1.0]),
)
"""Multipliers of any sign and size, NaN and infinities included."""
coefficient = st.one_of(
    st.floats(-1e3, 1e3),
    st.sampled_from([0.0, 1.0, -1.0, 1e-300, 1e200, 3.5748407272564336e-09]),
)


def _dot(a: np.ndarray, x: np.ndarray) -> Fraction:
    return sum((Fraction(float(u)) * Fraction(float(v)) for u, v in zip(a, x, strict=True)),
               Fraction(0))  # fmt: skip


def _down(q: Fraction) -> float:
    f = float(q)
    return math.nextafter(f, -math.inf) if Fraction(f) > q else f


def _up(q: Fraction) -> float:
    f = float(q)
    return math.nextafter(f, math.inf) if Fraction(f) < q else f


def _rows_around(dense: np.ndarray, x0: np.ndarray, slack: list[float], sides: list[int]):
    """Row bounds that hold at ``x0`` exactly: ``A x0`` rounded outward, widened by
    ``slack``, and with a side dropped (``sides``: 0 both, 1 no lower, 2 no upper)."""
    row_lo, row_hi = [], []
    for a, s, side in zip(dense, slack, sides, strict=True):
        value = _dot(a, x0)
        row_lo.append(-math.inf if side == 1 else _down(value - Fraction(s)))
        row_hi.append(math.inf if side == 2 else _up(value + Fraction(s)))
    return np.array(row_lo), np.array(row_hi)


def _assert_valid(bound: float, objective: np.ndarray, x0: np.ndarray) -> None:
    assert not math.isnan(bound)
    assert bound != math.inf  # the polytope holds x0: it is not empty
    if bound != -math.inf:
        assert Fraction(bound) <= _dot(objective, x0), (bound, float(_dot(objective, x0)))


@settings(max_examples=400, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data(), m=st.integers(1, 6), n=st.integers(1, 6))
def test_any_multipliers_give_a_valid_bound(data: st.DataObject, m: int, n: int) -> None:
    dense = np.array(data.draw(st.lists(st.lists(coefficient, min_size=n, max_size=n),
                                        min_size=m, max_size=m)))  # fmt: skip
    x0 = np.array(data.draw(st.lists(st.floats(-1e6, 1e6), min_size=n, max_size=n)))
    widths = data.draw(
        st.lists(st.sampled_from([0.0, 1e-12, 1.0, math.inf]), min_size=n, max_size=n)
    )
    box = np.array([[x - w, x + w] for x, w in zip(x0, widths, strict=True)])
    slack = data.draw(st.lists(st.sampled_from([0.0, 0.0, 1e-9, 1.0]), min_size=m, max_size=m))
    sides = data.draw(st.lists(st.sampled_from([0, 0, 1, 2]), min_size=m, max_size=m))
    row_lo, row_hi = _rows_around(dense, x0, slack, sides)
    assume(np.all(np.isfinite(box[:, 0]) | (box[:, 0] == -math.inf)))
    objective = np.array(data.draw(st.lists(coefficient, min_size=n, max_size=n)))
    multipliers = np.array(data.draw(st.lists(garbage, min_size=m, max_size=m)))
    csc = sparse.csc_matrix(dense)
    _assert_valid(safe_lower_bound(csc, row_lo, row_hi, objective, multipliers, box),
                  objective, x0)  # fmt: skip


@settings(max_examples=200, deadline=None, suppress_health_check=list(HealthCheck))
@given(data=st.data(), m=st.integers(1, 5), n=st.integers(1, 5))
def test_exact_multipliers_on_a_point_box_never_overshoot(
    data: st.DataObject, m: int, n: int
) -> None:
    """Box ``[x0, x0]`` and rows through ``A x0``: the minimum is ``c x0`` itself; with
    ``c = A^T y`` the multipliers ``y`` are exact, and the bound must stay below by
    rounding outward, never land above."""
    dense = np.array(data.draw(st.lists(st.lists(st.floats(-10, 10), min_size=n, max_size=n),
                                        min_size=m, max_size=m)))  # fmt: skip
    x0 = np.array(data.draw(st.lists(st.floats(-1e3, 1e3), min_size=n, max_size=n)))
    y = np.array(data.draw(st.lists(st.floats(-10, 10), min_size=m, max_size=m)))
    objective = dense.T @ y
    row_lo, row_hi = _rows_around(dense, x0, [0.0] * m, [0] * m)
    box = np.stack([x0, x0], axis=-1)
    bound = safe_lower_bound(sparse.csc_matrix(dense), row_lo, row_hi, objective, y, box)
    _assert_valid(bound, objective, x0)
    assert bound > -math.inf


def _relaxation_with_point(seed: int):
    """The relaxation of a random world's graph over its hull boxes, its rows widened (if
    need be) to hold exactly at one point of the box: the truth, lifted and clipped."""
    log, truth = simulate_random_world(seed=seed, n_poses=6, n_landmarks=3, size=(20.0, 15.0))
    graph = KinematicGraph.from_log(log)
    result = propagate(graph)
    values = np.clip(0.5 * (result.lo + result.hi), result.lo, result.hi)
    for pose, xyt in zip(truth.pose_ids, truth.poses_xyt, strict=True):
        k = graph.pose_index(pose)
        values[k : k + 2] = xyt[:2]
    values = np.clip(np.where(np.isfinite(values), values, 0.0), result.lo, result.hi)
    relaxation = relax(graph.factor_table(), result.lo, result.hi)
    x0 = np.clip(relaxation.lift(values), relaxation.col_lo, relaxation.col_hi)
    dense = relaxation.matrix.toarray()
    row_lo, row_hi = relaxation.row_lo.copy(), relaxation.row_hi.copy()
    for i, a in enumerate(dense):
        value = _dot(a, x0)
        if math.isfinite(row_lo[i]) and Fraction(row_lo[i]) > value:
            row_lo[i] = _down(value)
        if math.isfinite(row_hi[i]) and Fraction(row_hi[i]) < value:
            row_hi[i] = _up(value)
    box = np.stack([relaxation.col_lo, relaxation.col_hi], axis=-1)
    return relaxation.matrix.tocsc(), row_lo, row_hi, box, x0


def _lp_multipliers(
    csc: sparse.csc_matrix,
    row_lo: np.ndarray,
    row_hi: np.ndarray,
    box: np.ndarray,
    objective: np.ndarray,
) -> np.ndarray:
    """HiGHS's row duals for ``min objective @ x`` over the polytope (zeros if it fails)."""
    solver = highspy.Highs()
    solver.setOptionValue("output_flag", False)
    solver.passModel(_model(csc, row_lo, row_hi, box))
    solver.changeColsCost(len(objective), np.arange(len(objective)), objective)
    solver.run()
    duals = np.asarray(solver.getSolution().row_dual, dtype=float)
    return duals if duals.shape == (csc.shape[0],) else np.zeros(csc.shape[0])


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(
    seed=st.integers(0, 2**20),
    data=st.data(),
    mode=st.sampled_from(["garbage", "scaled", "flipped", "noisy", "zero"]),
)
def test_lp_multipliers_spoiled_any_way_still_bound(
    seed: int, data: st.DataObject, mode: str
) -> None:
    """On a real relaxation: the LP's own multipliers spoiled (scaled by huge or tiny
    factors, signs flipped, noise, zeros) or replaced by garbage, for a column's min or max."""
    csc, row_lo, row_hi, box, x0 = _relaxation_with_point(seed)
    m, n = csc.shape
    assume(m > 0)
    j = data.draw(st.integers(0, n - 1))
    sense = data.draw(st.sampled_from([1.0, -1.0]))
    objective = np.zeros(n)
    objective[j] = sense
    lower, upper = certified_bounds(csc, row_lo, row_hi, box, [j], WarmStarts())
    assert lower[0] <= x0[j] <= upper[0]  # the LP route itself
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    y = _lp_multipliers(csc, row_lo, row_hi, box, objective)
    if mode == "garbage":
        y = rng.normal(size=m) * 10.0 ** rng.integers(-300, 300, size=m)
    elif mode == "scaled":
        y = y * data.draw(st.sampled_from([1e-300, 1e-8, 0.5, 2.0, 1e8, 1e300]))
    elif mode == "flipped":
        y = np.where(rng.random(m) < 0.5, -y, y)
    elif mode == "noisy":
        y = y + rng.normal(size=m) * 1e-9 * (1.0 + np.abs(y))
    elif mode == "zero":
        y = np.where(rng.random(m) < 0.5, 0.0, y)
    _assert_valid(safe_lower_bound(csc, row_lo, row_hi, objective, y, box), objective, x0)


def test_a_wrong_sign_round_off_on_a_one_sided_row_costs_nothing() -> None:
    """min x over {x >= 1 (a row with no upper side), x in [0, 10]}: the exact multiplier is
    1; a simplex may return it with a 1e-13 multiplier of the wrong sign on another row with
    no lower side, which alone would make the bound -inf. It is dropped: the bound is the
    exact multiplier's (1 rounded outward by a few ulps)."""
    dense = np.array([[1.0], [1.0]])
    row_lo = np.array([1.0, -math.inf])
    row_hi = np.array([math.inf, 20.0])
    box = np.array([[0.0, 10.0]])
    objective = np.array([1.0])
    exact = safe_lower_bound(sparse.csc_matrix(dense), row_lo, row_hi, objective,
                             np.array([1.0, 0.0]), box)  # fmt: skip
    noisy = safe_lower_bound(sparse.csc_matrix(dense), row_lo, row_hi, objective,
                             np.array([1.0, 1e-13]), box)  # fmt: skip
    assert 1.0 - 1e-14 < exact <= 1.0
    assert noisy == exact


@settings(
    max_examples=15, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
@given(seed=st.integers(0, 2**20))
def test_sequence_kernel_bounds_every_column_like_highs(seed: int) -> None:
    """The minima and maxima of every column, solved as one sequence (HiGHS's first
    optimum, then the compiled simplex from it), keep the point exactly and are as tight
    as HiGHS alone on each LP (to its optimality tolerance relative to the box).

    The same worlds on every run (a fresh clone's CI drew seed 1052, on which the
    tightness does not hold: see the strict xfail below)."""
    relaxation = _relaxation_with_point(seed)
    assume(relaxation[0].shape[0] > 0)
    _check_sequence_kernel(*relaxation)


@pytest.mark.xfail(
    strict=True,
    reason="the compiled simplex's inverse, updated 500 times between refactorizations, "
    "drifts: its multipliers bound the maxima of columns 13 and 14 3.1e-5 above HiGHS's "
    "(sound, looser); refactoring every 100 pivots closes it but costs 0.3 s on cuikslam "
    "paper (issue 27's 2 s)",
)
def test_sequence_kernel_bounds_like_highs_on_seed_1052() -> None:
    """The example a fresh clone's CI drew (2026-11-28)."""
    _check_sequence_kernel(*_relaxation_with_point(1052))


def _check_sequence_kernel(
    csc: sparse.csc_matrix, row_lo: np.ndarray, row_hi: np.ndarray, box: np.ndarray, x0
) -> None:
    n = csc.shape[1]
    columns = list(range(n))
    lower, upper = certified_bounds(csc, row_lo, row_hi, box, columns, WarmStarts())
    for j in columns:
        assert Fraction(lower[j]) <= Fraction(float(x0[j])) <= Fraction(upper[j]), j
    lp_bounds.SEQUENCE_KERNEL = False
    try:
        alone_lo, alone_hi = certified_bounds(csc, row_lo, row_hi, box, columns, WarmStarts())
    finally:
        lp_bounds.SEQUENCE_KERNEL = True
    scale = 1e-6 * (1.0 + np.abs(box).max(axis=1))
    finite = np.isfinite(alone_lo)
    assert np.all(np.asarray(lower)[finite] >= np.asarray(alone_lo)[finite] - scale[finite])
    finite = np.isfinite(alone_hi)
    assert np.all(np.asarray(upper)[finite] <= np.asarray(alone_hi)[finite] + scale[finite])


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2**20))
def test_reused_multipliers_give_the_same_bounds_and_stay_sound(seed: int) -> None:
    """Bounds from the last LPs' multipliers without solving: on the same polytope they
    keep the point and are the LPs' bounds up to the multipliers' single precision; on
    other rows (here each row bound moved out by up to 10 %, the
    point still inside) they still keep the point."""
    csc, row_lo, row_hi, box, x0 = _relaxation_with_point(seed)
    m, n = csc.shape
    assume(m > 0)
    columns = list(range(n))
    warm = WarmStarts()
    lower, upper = certified_bounds(csc, row_lo, row_hi, box, columns, warm)
    again_lo, again_hi = certified_bounds(csc, row_lo, row_hi, box, columns, warm, reuse=True)
    for j in columns:
        assert Fraction(again_lo[j]) <= Fraction(float(x0[j])) <= Fraction(again_hi[j]), j
    # kept in single precision: within about 1e-7 of the terms (boxes of metres here)
    scale = 1e-5 * (1.0 + np.abs(box).max(axis=1))
    for again, first in ((again_lo, lower), (again_hi, upper)):
        again, first = np.asarray(again), np.asarray(first)
        assert np.array_equal(np.isfinite(again), np.isfinite(first))
        finite = np.isfinite(first)
        assert np.all(np.abs(again[finite] - first[finite]) <= scale[finite])
    rng = np.random.default_rng(seed)
    moved_lo = row_lo - 0.1 * rng.random(m) * np.abs(row_lo)
    moved_hi = row_hi + 0.1 * rng.random(m) * np.abs(row_hi)
    lower, upper = certified_bounds(csc, moved_lo, moved_hi, box, columns, warm, reuse=True)
    for j in columns:
        assert Fraction(lower[j]) <= Fraction(float(x0[j])) <= Fraction(upper[j]), j
