"""Branches share one graph and hold only overlays: that must change nothing but cost.

Every child built on the shared graph must have, bit for bit, the boxes a private full
copy of its parent would get from the same propagation; maintenance (rebasing the shared
boxes, compacting the factor pool) must not change any result; and the live branches must
not hold anything close to a full copy each.
"""

from __future__ import annotations

import numpy as np
import pytest

from cuikslam.graph.encoding import KIND, NO_FACTOR, OBSERVATION, ODOMETRY
from cuikslam.hypotheses import _shared, joined, search, solve_unknown
from cuikslam.hypotheses import survivors as after_search
from cuikslam.hypotheses._gates import gate
from cuikslam.hypotheses._shared import EMPTY_OVERLAY, Overlay, SharedGraph
from cuikslam.hypotheses.expansions import Expansions
from cuikslam.hypotheses.explorer import Explorer, Node
from cuikslam.hypotheses.problem import build_problem
from cuikslam.hypotheses.search import explore
from cuikslam.hypotheses.tree import SearchLimit
from cuikslam.narrowing._factors import fresh_memory
from cuikslam.narrowing._propagate import INCONSISTENT, propagate_arrays, propagate_buffered
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL
from cuikslam.simulate import simulate_paper, simulate_random_world


def _explored(log, max_nodes: int = 10**6) -> tuple[Explorer, Node, object]:
    """A hull-level search of ``log``, stopped after ``max_nodes`` expansions."""
    explorer = Explorer(build_problem(log), DEFAULT_RTOL, "hull", 0, local=False)
    root = explorer.root()
    assert root is not None
    return explorer, root, explore(explorer, root, SearchLimit(max_nodes=max_nodes), 10**6)


def _full_copy_child(
    graph: SharedGraph, overlay: Overlay, ids: np.ndarray
) -> tuple[int, np.ndarray, np.ndarray]:
    """The child the old way: a private copy of the parent plus rows ``ids``, propagated."""
    child_rows = np.union1d(overlay.rows, ids[~graph.in_base[ids]])
    lo, hi, arrays = graph.standalone(Overlay(overlay.idx, overlay.lo, overlay.hi, child_rows))
    table_ids = np.union1d(np.flatnonzero(graph.in_base[: graph.n_rows]), child_rows)
    touched = np.searchsorted(table_ids, ids)
    status, _ = propagate_arrays(
        lo, hi, arrays.factors, arrays.head, arrays.entry_factor, arrays.entry_next,
        touched, graph.rtol, graph.max_rounds, 2**62,
    )  # fmt: skip
    return status, lo, hi


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return np.array_equal(a.view(np.int64), b.view(np.int64))


def test_every_child_equals_a_full_copy(monkeypatch: pytest.MonkeyPatch) -> None:
    """During whole searches (maintenance forced often), compare every child."""
    monkeypatch.setattr(_shared, "MIN_MAINTENANCE_LOAD", 8)
    monkeypatch.setattr(search, "MAINTAIN_EVERY", 16)
    checked = {"children": 0, "empty": 0}
    original = SharedGraph.add_rows

    def checked_add_rows(graph: SharedGraph, overlay: Overlay, ids: np.ndarray) -> Overlay | None:
        parent = graph.materialize(overlay)
        status, lo, hi = _full_copy_child(graph, overlay, ids)
        child = original(graph, overlay, ids)
        assert (child is None) == (status == INCONSISTENT)
        if child is None:
            checked["empty"] += 1
        else:
            mine_lo, mine_hi = graph.materialize(child)
            assert _same_bits(mine_lo, lo) and _same_bits(mine_hi, hi)
            checked["children"] += 1
        after = graph.materialize(overlay)  # the parent is never changed
        assert _same_bits(after[0], parent[0]) and _same_bits(after[1], parent[1])
        working = graph.materialize(graph.current)  # the cache holds what it says it holds
        assert _same_bits(graph.lo, working[0]) and _same_bits(graph.hi, working[1])
        return child

    monkeypatch.setattr(SharedGraph, "add_rows", checked_add_rows)
    solve_unknown(simulate_paper(seed=0, unknown=True)[0], consistency="hull", local_frame=False)
    for seed, n_poses, size in ((1, 30, (30.0, 20.0)), (2, 40, (60.0, 45.0))):
        log, _ = simulate_random_world(
            seed=seed, n_poses=n_poses, n_landmarks=6, size=size, unknown=True
        )
        solve_unknown(log, consistency="hull", max_nodes=400, local_frame=False)
    assert checked["children"] > 1000 and checked["empty"] > 100


def _fingerprint(solution) -> list:
    return [(h.assignment, h.poses.tobytes(), h.landmarks.tobytes()) for h in solution.hypotheses]


WORLDS = [(1, 30, (30.0, 20.0)), (0, 40, (60.0, 45.0)), (2, 40, (60.0, 45.0))]


@pytest.mark.parametrize(("seed", "n_poses", "size"), WORLDS)
def test_maintenance_changes_no_result(
    seed: int, n_poses: int, size: tuple[float, float], monkeypatch: pytest.MonkeyPatch
) -> None:
    log, _ = simulate_random_world(
        seed=seed, n_poses=n_poses, n_landmarks=6, size=size, unknown=True
    )
    # many survivors make the comparison strong: bisection would refute most of them
    monkeypatch.setattr(after_search, "BISECTION_MIN_PARTS", 0)
    monkeypatch.setattr(after_search, "BISECTION_PARTS_PER_NODE", 0)
    monkeypatch.setattr("cuikslam.hypotheses.explorer.LEAF_BISECTION_PARTS", 0)
    monkeypatch.setattr(_shared, "MIN_MAINTENANCE_LOAD", 10**12)
    # depth first, so that 300 expansions find many survivors (test_joined.py: with lanes)
    monkeypatch.setattr(joined, "JOIN_MAX_LANES", 1)
    never = solve_unknown(log, consistency="hull", max_nodes=300, local_frame=False)
    calls = {"rebase": 0, "compact": 0, "renamed": 0}
    for name in ("rebase", "compact"):
        original = getattr(SharedGraph, name)

        def counted(graph, overlays, name=name, original=original):
            calls[name] += 1
            return original(graph, overlays)

        monkeypatch.setattr(SharedGraph, name, counted)
    renamed = Expansions.renamed

    def counted_renames(kept, new):
        calls["renamed"] += len(kept) > 0
        return renamed(kept, new)

    monkeypatch.setattr(Expansions, "renamed", counted_renames)
    monkeypatch.setattr(_shared, "MIN_MAINTENANCE_LOAD", 4)
    monkeypatch.setattr(search, "MAINTAIN_EVERY", 4)
    often = solve_unknown(log, consistency="hull", max_nodes=300, local_frame=False)
    assert len(never.hypotheses) > 10
    assert calls["rebase"] >= 3 and calls["compact"] >= 1
    assert calls["renamed"] >= 3  # kept expansions of the dive re-expressed too
    assert _fingerprint(never) == _fingerprint(often)


def test_pending_nodes_hold_no_full_copies() -> None:
    log, _ = simulate_random_world(
        seed=1, n_poses=80, n_landmarks=10, size=(30.0, 20.0), unknown=True
    )
    explorer, _, outcome = _explored(log, max_nodes=300)
    graph = explorer.graph
    overlays = [n.overlay for n in outcome.unexplored + outcome.survivors]
    assert len(overlays) > 16
    n_vars = len(graph.base_lo)
    full_copy_bytes = 2 * graph.base_lo.nbytes + graph.n_rows * graph.rows[0].nbytes
    assert max(len(o.idx) for o in overlays) < n_vars / 2
    assert max(o.nbytes for o in overlays) < full_copy_bytes / 4


def test_the_frontier_does_not_grow_with_the_survivors() -> None:
    """Depth first: the pending nodes are one path's siblings, however many survive."""
    explorer, _, outcome = _explored(simulate_paper(seed=0, unknown=True)[0])
    assert explorer.stats.survivors == len(outcome.survivors) > 400
    assert explorer.stats.peak_frontier <= len(explorer.problem.decisions) + 1


def test_rebase_moves_the_common_bounds_and_keeps_every_branch() -> None:
    lo, hi = np.zeros(6), np.full(6, 10.0)
    graph = SharedGraph(lo, hi, np.arange(3), DEFAULT_RTOL, DEFAULT_ROUNDS)
    idx = np.array([1, 4])
    overlays = [
        Overlay(idx, np.array([2.0, 0.0]), np.array([3.0, 9.0]), EMPTY_OVERLAY.rows),
        Overlay(idx, np.array([2.0, 0.0]), np.array([3.0, 8.0]), EMPTY_OVERLAY.rows),
        Overlay(idx[:1], np.array([2.0]), np.array([3.0]), EMPTY_OVERLAY.rows),
        EMPTY_OVERLAY,
    ]
    before = [graph.materialize(o) for o in overlays]
    rebased = graph.rebase(overlays)
    assert (graph.base_lo[1], graph.base_hi[1]) == (2.0, 3.0)  # 3 of 4 branches
    assert graph.base_hi[4] == 10.0  # two different values against two at the base
    for (blo, bhi), o in zip(before, rebased, strict=True):
        lo_, hi_ = graph.materialize(o)
        assert _same_bits(lo_, blo) and _same_bits(hi_, bhi)
    assert sum(len(o.idx) for o in rebased) < sum(len(o.idx) for o in overlays)
    signed_zero = np.where(np.arange(6) == 5, -0.0, graph.base_lo)  # differs from 0.0 in bits
    assert list(graph.overlay_of(signed_zero, graph.base_hi, idx).idx) == [5]


def test_buffered_propagation_leaves_its_buffers_clean() -> None:
    """Many small propagations share work arrays: each must leave them as it found them."""
    log, _ = simulate_paper(seed=0, unknown=False)
    explorer, root, _ = _explored(log)
    lo, hi, arrays = explorer.graph.standalone(root.overlay)
    graph = (arrays.factors, arrays.head, arrays.entry_factor, arrays.entry_next)
    n = len(arrays.factors)
    everything = np.arange(n)
    queue, state = np.empty(n + 1, dtype=np.int64), np.zeros(n, dtype=np.int8)
    memory, applied = fresh_memory(n), np.empty(n, dtype=np.int64)
    wide_lo, wide_hi = lo - 5.0, hi + 5.0
    x0 = min(explorer.problem.pose_x.values())
    empty_hi = np.where(np.arange(len(lo)) == x0, wide_lo - 1.0, wide_hi)
    for start_hi in (wide_hi, empty_hi):
        expected = (wide_lo.copy(), start_hi.copy())
        status, count = propagate_arrays(*expected, *graph, everything, DEFAULT_RTOL, 1, 2**62)
        got = (wide_lo.copy(), start_hi.copy())
        status2, count2, n_applied = propagate_buffered(
            *got, *graph, everything, DEFAULT_RTOL, 1, 2**62, queue, state, memory, applied, False
        )
        assert (status, count) == (status2, count2) and n_applied > 0
        if status != INCONSISTENT:
            assert _same_bits(got[0], expected[0]) and _same_bits(got[1], expected[1])
        assert not state.any()
        assert np.array_equal(memory, fresh_memory(n))
    assert status == INCONSISTENT  # the second start box is empty at variable 0


def test_switched_off_rows_are_never_applied() -> None:
    log, _ = simulate_paper(seed=0, unknown=False)
    explorer, root, _ = _explored(log)
    lo, hi, arrays = explorer.graph.standalone(root.overlay)
    factors = arrays.factors.copy()
    factors[factors[:, KIND] == OBSERVATION, KIND] = NO_FACTOR
    wide = (lo - 50.0, hi + 50.0)
    out_lo, out_hi = wide[0].copy(), wide[1].copy()
    _, count = propagate_arrays(
        out_lo, out_hi, factors, arrays.head, arrays.entry_factor, arrays.entry_next,
        np.arange(len(factors)), DEFAULT_RTOL, 1, 2**62,
    )  # fmt: skip
    assert count >= np.count_nonzero(factors[:, KIND] == ODOMETRY)
    for x in explorer.problem.named_x:  # only observations touch landmarks
        assert out_lo[x] == wide[0][x] and out_hi[x] == wide[1][x]


def test_gate_many_is_gate_per_landmark() -> None:
    log, _ = simulate_paper(seed=0, unknown=True)
    explorer, _, outcome = _explored(log)
    graph = explorer.graph
    node = outcome.survivors[0]
    lo, hi = graph.materialize(node.overlay)
    xs = explorer.landmark_xs(node)
    for d in explorer.problem.decisions:
        many = graph.gate(node.overlay, d.pose_x, xs, d.bearing_var, d.range_var)
        one = [gate(lo, hi, d.pose_x, int(x), d.bearing_var, d.range_var) for x in xs]
        assert list(many) == one


def test_a_met_box_keeps_angles_in_the_branch_s_turn() -> None:
    """:meth:`SharedGraph.met` meets plain variables as intervals and angles modulo 2 pi:
    a heading given one turn up still narrows the branch's, which stays in its own turn."""
    explorer, root, _ = _explored(simulate_paper(seed=0, unknown=True)[0], max_nodes=1)
    graph = explorer.graph
    lo, hi = graph.materialize(root.overlay)
    theta = explorer.problem.pose_x[max(explorer.problem.pose_x)] + 2
    x = theta - 2
    assert theta in graph.angle_variables() and x not in graph.angle_variables()
    assert 0.02 < hi[theta] - lo[theta] < 6.0 and hi[x] - lo[x] > 0.02
    other_lo, other_hi = lo.copy(), hi.copy()
    mid = 0.5 * (lo[theta] + hi[theta])
    other_lo[theta], other_hi[theta] = mid + 2 * np.pi, hi[theta] + 2 * np.pi + 1.0
    other_lo[x] = 0.5 * (lo[x] + hi[x])
    met = graph.met(root.overlay, other_lo, other_hi)
    assert met is not None
    new_lo, new_hi = graph.materialize(met)
    assert mid - 1e-12 <= new_lo[theta] <= mid + 1e-12 < new_hi[theta] <= hi[theta]
    assert new_lo[x] == other_lo[x] and new_hi[x] <= hi[x]
    assert np.all(new_lo >= lo) and np.all(new_hi <= hi)
    other_lo[theta], other_hi[theta] = hi[theta] + 0.01, hi[theta] + 0.02  # no turn meets it
    assert graph.met(root.overlay, other_lo, other_hi) is None
