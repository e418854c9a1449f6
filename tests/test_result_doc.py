"""docs/result-format.md names every key a result JSON has (so the page stays true)."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import pytest

from cuikslam.hypotheses.explorer import SearchStatistics
from cuikslam.results.io import solution_to_json
from cuikslam.simulate import simulate_paper
from cuikslam.solver import solve

DOC = Path(__file__).resolve().parents[1] / "docs" / "result-format.md"
ID_KEYED = ("poses", "landmarks")
"""Objects keyed by pose or landmark id, not by a fixed name."""


def _keys(document: object, parent: str = "") -> set[str]:
    """Every key of ``document``, its objects' and its lists' objects' (ids excluded)."""
    found: set[str] = set()
    if isinstance(document, dict):
        for key, value in document.items():
            if parent not in ID_KEYED:
                found.add(key)
            found |= _keys(value, key if parent not in ID_KEYED else "")
    elif isinstance(document, list):
        for value in document:
            found |= _keys(value, parent)
    return found


@pytest.fixture(scope="module")
def documents() -> list[dict]:
    known = solve(simulate_paper(seed=0)[0], consistency="hull", work_budget=None)
    unknown = solve(simulate_paper(seed=0, unknown=True)[0], consistency="hull", work_budget=7e6)
    return [solution_to_json(known), solution_to_json(unknown)]


def test_every_key_of_a_result_is_documented(documents: list[dict]) -> None:
    # a key is named as `key`, or as "key" inside a code span or the example
    named = set(re.findall(r"[`\"]([a-z_]+)[`\"]", DOC.read_text(encoding="utf-8")))
    keys = set().union(*(_keys(d) for d in documents))
    assert {"witness", "correspondence", "pose_hull", "branch_points"} <= keys  # all kinds seen
    assert keys - named == set()


def test_every_key_of_a_split_search_is_documented() -> None:
    """A search split over a (thread) cluster adds its own counts and timings."""
    pytest.importorskip("distributed", reason='needs Dask: pip install "cuikslam[distributed]"')
    from cuikslam.cluster import dask_client
    from cuikslam.hypotheses.distributed import search_distributed

    log = simulate_paper(seed=0, unknown=True)[0]
    with dask_client(workers=1, processes=False) as client:
        solution = search_distributed(log, client=client, consistency="hull", max_hypotheses=10)
    named = set(re.findall(r"[`\"]([a-z_]+)[`\"]", DOC.read_text(encoding="utf-8")))
    keys = _keys(solution_to_json(solution))
    assert {"tasks", "worker_cpu_s", "split_s", "client_s"} <= keys
    assert keys - named == set()


def test_the_search_counts_the_page_lists_are_the_search_statistics() -> None:
    text = DOC.read_text(encoding="utf-8")
    for field in dataclasses.fields(SearchStatistics):
        assert f"`{field.name}`" in text, field.name
