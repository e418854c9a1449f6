"""The figure of ``cuikslam paper`` drawn in a second process (cuikslam.cli.figure_job)."""

from __future__ import annotations

from pathlib import Path

import pytest

from cuikslam.cli._common import CommandError
from cuikslam.cli.figure_job import start_figure
from cuikslam.simulate.paper import simulate_paper
from cuikslam.solver import solve

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def paper_solution():
    log, truth = simulate_paper(seed=0)
    return solve(log, consistency="hull", certify_limit=0, work_budget=None), truth


@pytest.mark.parametrize("child", [True, False])
def test_the_figure_is_written_by_a_child_or_here(tmp_path: Path, paper_solution, child) -> None:
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=child)
    assert (job.process is not None) == child
    job.send(*paper_solution)
    job.finish()
    data = path.read_bytes()
    assert data.startswith(PNG_MAGIC) and len(data) > 10_000
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


def test_a_child_that_cannot_write_names_the_file(tmp_path: Path, paper_solution) -> None:
    path = tmp_path / "gone" / "paper.png"  # the folder does not exist
    job = start_figure(str(path), child=True)
    job.send(*paper_solution)
    with pytest.raises(CommandError, match=r"gone/paper\.png: cannot write"):
        job.finish()
    assert not path.exists()


def test_a_cancelled_child_writes_nothing(tmp_path: Path) -> None:
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=True)
    process = job.process
    job.cancel()
    assert job.process is None and process is not None and process.returncode is not None
    assert not path.exists()


def test_a_child_given_nothing_exits_quietly(tmp_path: Path) -> None:
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=True)
    assert job.process is not None and job.process.stdin is not None
    job.process.stdin.close()  # the parent went away before sending
    assert job.process.wait(timeout=120) == 0
    assert not path.exists()
