"""The correspondence summary: certain associations and independent ambiguities."""

from __future__ import annotations

import itertools
import math

import numpy as np

from cuikslam.hypotheses import solve_unknown
from cuikslam.results.solution import Hypothesis
from cuikslam.results.summary import describe, summarize
from cuikslam.simulate import simulate_paper


def _hypothesis(assignment: list[str], lo: float = 0.0, hi: float = 1.0) -> Hypothesis:
    box = np.array([[[lo, hi]] * 3])
    ids = sorted(set(assignment))
    return Hypothesis(assignment, [0], box, ids, ["c"] * len(ids), np.zeros((0, 2, 2)))


def test_a_product_of_ambiguities_is_found_and_a_dependence_is_kept_together() -> None:
    # observation 1 may join A or start B; independently, 3 may join C or D
    product = [
        _hypothesis(["A", one, "C", three])
        for one, three in itertools.product(["A", "B"], ["C", "D"])
    ]
    s = summarize([h.assignment for h in product])
    assert s.certain == [True, False, True, False]
    assert [f.observations for f in s.factors] == [[1], [3]]
    assert s.combinations == 4
    # a parity dependence among three observations is not pairwise visible: one group
    xor = [
        _hypothesis(["A", *["A" if bit else f"N{i}" for i, bit in enumerate(bits, 1)]])
        for bits in itertools.product([0, 1], repeat=3)
        if sum(bits) % 2 == 0
    ]
    s = summarize([h.assignment for h in xor])
    assert [f.observations for f in s.factors] == [[1, 2, 3]]
    assert s.combinations == len(xor) == 4


def test_the_search_summarises_every_survivor_not_only_the_reported() -> None:
    log, _ = simulate_paper(seed=0, unknown=True)
    every = solve_unknown(log, consistency="hull", local_frame=False, max_hypotheses=1000)
    few = solve_unknown(log, consistency="hull", local_frame=False, max_hypotheses=2)
    assert few.correspondence["follows"] == every.correspondence["follows"]
    assert few.correspondence["factors"] == every.correspondence["factors"]
    assert few.correspondence["survivors"] == len(every.hypotheses) > 2
    lo = np.min([h.poses[..., 0] for h in every.hypotheses], axis=0)
    hi = np.max([h.poses[..., 1] for h in every.hypotheses], axis=0)
    assert np.array_equal(np.array(few.correspondence["pose_hull"]), np.stack([lo, hi], -1))
    assert any(f"{len(every.hypotheses)} survivors)" in m for m in few.messages)


def test_the_paper_survivors_are_a_product_of_independent_ambiguities() -> None:
    log, truth = simulate_paper(seed=0, unknown=True)
    solution = solve_unknown(log, consistency="hull")
    c = solution.correspondence
    assert c is not None and c["survivors"] == c["reported"] == len(solution.hypotheses)
    assert math.prod(len(f["choices"]) for f in c["factors"]) == len(solution.hypotheses)
    true_follows = summarize([truth.assignment]).follows
    for i, options in enumerate(c["follows"]):
        assert true_follows[i][0] in options
        assert c["certain"][i] == (len(options) == 1)


def test_the_summary_line_says_each_shape_of_ambiguity_once() -> None:
    """One ambiguous observation, one group of several, several groups: the line names the
    group sizes only when there are several (never "100 = 100 combinations")."""
    one = summarize([["A", "A", "B"], ["A", "B", "B"]])
    assert describe(one, 2) == (
        "1 of 3 observations are associated for certain; 2 are ambiguous, in one group "
        "(2 combinations: the 2 survivors)"
    )
    lone = summarize([["A", "B"], ["A", "A"]])
    assert describe(lone, 2) == (
        "1 of 2 observations are associated for certain; 1 is ambiguous "
        "(2 combinations: the 2 survivors)"
    )
    product = summarize([["A", "A", "B", "C"], ["A", "B", "B", "C"],
                         ["A", "A", "B", "B"], ["A", "B", "B", "B"]])  # fmt: skip
    assert describe(product, 4, complete=False) == (
        "in the survivors found so far (the search is incomplete), 1 of 4 observations are "
        "associated for certain; 3 are ambiguous, in 2 independent groups (2 x 2 = 4 "
        "combinations: the 4 survivors)"
    )


def test_a_summary_of_some_survivors_says_so() -> None:
    """When the tally holds only the first survivors (a cap), "certain" speaks of those."""
    some = summarize([["A", "A", "B"], ["A", "B", "B"]])
    line = describe(some, 5, summarised=2)
    assert line.startswith("in the first 2 of the 5 survivors (the rest counted only), ")
    assert line.endswith("(2 combinations: the 2 survivors)")
    assert describe(some, 2, summarised=2) == describe(some, 2)
