"""The reproducers of issue 9, as regression tests (``tests/data/repro``, see its README),
and the minimal failing worlds the property tests found (``tests/data/found``).

Each is a valid log; those with a ``.truth.json`` come from a known true world. With
default options the true partition must survive, its boxes must hold the exact truth
(headings modulo 2π), and ``cuikslam solve`` must exit 0 without a traceback (one solve,
by the command, for both checks). The others are consistent logs that crashed or ran for
minutes: they must exit 0 without a traceback, within a generous hang guard (not a
performance assertion: the default work budget bounds every solve).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from cuikslam.cli.warm_up import PARTS, warm_part
from cuikslam.hypotheses import solve_unknown
from cuikslam.log import Log, read_log_file
from cuikslam.results.io import read_result_file
from worlds import (
    SEARCH_LEVELS,
    Truth,
    log_violations,
    search_level,
    true_index,
    truth_misses,
)

REPRO = Path(__file__).parent / "data" / "repro"
FOUND = Path(__file__).parent / "data" / "found"
"""Minimal failing worlds of the property tests, kept (see its README)."""
WITH_TRUTH = sorted(p for p in REPRO.glob("*.jsonl") if p.with_suffix(".truth.json").is_file())
WITHOUT_TRUTH = sorted(p for p in REPRO.glob("*.jsonl") if p not in WITH_TRUTH)
CASES = WITH_TRUTH + sorted(FOUND.glob("*.jsonl"))
"""Every log with a truth file."""
HANG_GUARD = 300
"""Seconds before a subprocess counts as hung (the issue asks for 5 s end to end; each
solve takes a few seconds of CPU, so only a hang, not a busy machine, reaches this)."""


@pytest.fixture(scope="module", autouse=True)
def _compiled() -> None:
    """Compile the kernels into numba's cache first, so that the commands run here load
    them (a cold cache costs tens of seconds in the first one; not what these tests are
    about)."""
    for part in PARTS:
        warm_part(part)


def truth_of(log_path: Path) -> Truth:
    return Truth.from_file(log_path.with_name(log_path.stem + ".truth.json"))


def named_ids(log: Log) -> set[str]:
    """Landmark ids the log itself names: these are the true ids."""
    return {r.landmark for r in log.landmark_priors} | {
        o.landmark for o in log.observations if o.landmark is not None
    }


def run_cli(*args: object, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "COLUMNS": "200", "NO_COLOR": "1"}
    try:
        return subprocess.run(
            [sys.executable, "-m", "cuikslam.cli.main", *map(str, args)],
            cwd=cwd,
            capture_output=True,
            text=True,
            timeout=HANG_GUARD,
            env=env,
            check=False,
        )
    except subprocess.TimeoutExpired:
        pytest.fail(f"cuikslam {' '.join(map(str, args))} still running after {HANG_GUARD} s")


def test_every_reproducer_is_here() -> None:
    assert [p.name for p in WITH_TRUTH] == [
        "fov-true-refuted.jsonl",
        "mixed-true-refuted.jsonl",
        "mixed-truth-outside.jsonl",
    ]
    assert [p.name for p in WITHOUT_TRUTH] == [
        "certify-97s.jsonl",
        "lp-slow-or-hang.jsonl",
        "signed-zero-crash.jsonl",
        "subnormal-crash.jsonl",
    ]


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
def test_reproducer_measures_its_world(path: Path) -> None:
    """The test data itself: every interval holds the truth, every sensor rule holds."""
    assert log_violations(read_log_file(path), truth_of(path)) == []


@pytest.mark.parametrize("level", sorted(SEARCH_LEVELS))
@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
def test_reproducer_keeps_the_truth_at_every_level(path: Path, level: str) -> None:
    log, truth = read_log_file(path), truth_of(path)
    with search_level(level):
        solution = solve_unknown(log, **SEARCH_LEVELS[level])
    assert solution.complete
    index = true_index(solution, truth, named_ids(log))
    assert index >= 0, f"the true correspondence is not among {len(solution.hypotheses)} survivors"
    assert truth_misses(solution.hypotheses[index], truth, named_ids(log)) == []


@pytest.mark.parametrize("path", CASES, ids=lambda p: p.stem)
def test_reproducer_keeps_the_truth_with_default_options(path: Path, tmp_path: Path) -> None:
    """``cuikslam solve --truth`` passes its own truth check, and its result, checked here
    against the exact truth, keeps the true correspondence with the truth in every box."""
    truth_file = path.with_name(path.stem + ".truth.json")
    out = tmp_path / "out.json"
    result = run_cli("solve", path, "--json", out, "--truth", truth_file, cwd=tmp_path)
    assert "Traceback" not in result.stderr, result.stderr
    report = result.stdout[result.stdout.find("truth check") :][:2000]
    assert result.returncode == 0, report + result.stderr[-2000:]
    assert "all contain the truth" in result.stdout, report
    log, truth, solution = read_log_file(path), truth_of(path), read_result_file(out)
    assert not solution.refuted, solution.messages
    index = true_index(solution, truth, named_ids(log))
    assert index >= 0, (
        f"the true correspondence is not among {len(solution.hypotheses)} survivors "
        f"(complete: {solution.complete}; {solution.messages})"
    )
    assert truth_misses(solution.hypotheses[index], truth, named_ids(log)) == []


@pytest.mark.parametrize("path", WITHOUT_TRUTH, ids=lambda p: p.stem)
def test_reproducer_cli_exits_0(path: Path, tmp_path: Path) -> None:
    """Exit 0 without a traceback, and a well-formed result (the reader refuses NaN
    bounds) with the log's hypothesis: each of these logs is consistent. The signed zeros
    and subnormals are also solved in the test process at every level, their truth
    checked, in ``test_odd_numbers.py``."""
    result = run_cli("solve", path, "--json", tmp_path / "out.json", cwd=tmp_path)
    assert "Traceback" not in result.stderr, result.stderr
    assert result.returncode == 0, result.stdout[-2000:] + result.stderr[-2000:]
    solution = read_result_file(tmp_path / "out.json")
    assert solution.hypotheses and not solution.refuted, solution.messages
