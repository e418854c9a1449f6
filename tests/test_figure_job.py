"""The figure of ``cuikslam paper`` drawn in a second process (cuikslam.cli.figure_job)."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest

from cuikslam.cli._common import CommandError
from cuikslam.cli.figure_job import start_figure
from cuikslam.simulate.paper import simulate_paper
from cuikslam.solver import solve

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def paper_solution():
    """The known-correspondence solve, its truth and each observation's pose, and the
    unknown-correspondence solve (fast options: the figure is what is tested)."""
    log, truth = simulate_paper(seed=0)
    known = solve(log, consistency="hull", certify_limit=0, work_budget=None)
    unknown = solve(simulate_paper(seed=0, unknown=True)[0], consistency="hull", certify_limit=0)
    return (known, truth, [o.pose for o in log.observations]), unknown


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data.startswith(PNG_MAGIC)
    return struct.unpack(">II", data[16:24])


@pytest.mark.parametrize("child", [True, False])
def test_the_figure_is_written_by_a_child_or_here(tmp_path: Path, paper_solution, child) -> None:
    known, unknown = paper_solution
    assert len(unknown.hypotheses) == 2
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=child)
    assert (job.process is not None) == child
    job.send(*known)
    job.send_unknown(unknown)
    job.finish()
    width, height = png_size(path)
    assert width > 1.5 * height  # three panels side by side: the known solve, 2 survivors
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


def test_the_child_and_the_parent_draw_the_same_figure(tmp_path: Path, paper_solution) -> None:
    known, unknown = paper_solution
    for name, child in (("child.png", True), ("here.png", False)):
        job = start_figure(str(tmp_path / name), child=child)
        job.send(*known)
        job.send_unknown(unknown)
        job.finish()
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()


def test_a_child_that_cannot_write_names_the_file(tmp_path: Path, paper_solution) -> None:
    path = tmp_path / "gone" / "paper.png"  # the folder does not exist
    job = start_figure(str(path), child=True)
    job.send(*paper_solution[0])
    job.send_unknown(None)  # no second part: the known panel alone
    with pytest.raises(CommandError, match=r"gone/paper\.png: cannot write"):
        job.finish()
    assert not path.exists()


def test_a_child_stopped_after_the_first_part_writes_nothing(
    tmp_path: Path, paper_solution
) -> None:
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=True)
    job.send(*paper_solution[0])
    assert job.process is not None and job.process.stdin is not None
    job.process.stdin.close()  # the parent went away before the second part
    assert job.process.wait(timeout=120) == 0
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
