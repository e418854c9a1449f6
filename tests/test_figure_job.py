"""The figure of ``cuikslam paper`` drawn in a second process (cuikslam.cli.figure_job)."""

from __future__ import annotations

import copy
import re
import struct
from pathlib import Path

import pytest

from cuikslam.cli._common import CommandError
from cuikslam.cli.figure_job import start_figure
from cuikslam.results.figures import KnownUnknownFigure
from cuikslam.simulate.paper import simulate_paper
from cuikslam.solver import solve

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def paper_solution():
    """The unknown-correspondence solve, the truth and each observation's pose, and the
    known-correspondence solve (fast options: the figure is what is tested)."""
    log, truth = simulate_paper(seed=0)
    known = solve(log, consistency="hull", certify_limit=0, work_budget=None)
    unknown = solve(simulate_paper(seed=0, unknown=True)[0], consistency="hull", certify_limit=0)
    return (unknown, truth, [o.pose for o in log.observations]), known


def png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data.startswith(PNG_MAGIC)
    return struct.unpack(">II", data[16:24])


@pytest.mark.parametrize("child", [True, False])
def test_the_figure_is_written_by_a_child_or_here(tmp_path: Path, paper_solution, child) -> None:
    unknown, known = paper_solution
    assert len(unknown[0].hypotheses) == 2
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=child)
    assert (job.process is not None) == child
    job.send_unknown(*unknown)
    job.send_known(known)
    job.finish()
    width, height = png_size(path)
    assert width > 1.5 * height  # three panels side by side: the known solve, 2 survivors
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left behind


@pytest.mark.parametrize("suffix", [".png", ".svg"])
def test_the_child_and_the_parent_draw_the_same_figure(
    tmp_path: Path, paper_solution, suffix: str
) -> None:
    # a PNG: the child draws the known panel onto the canvas it drew the rest on, the
    # parent draws it all at once; an SVG: the child too draws it all at once
    unknown, known = paper_solution
    for name, child in (("child", True), ("here", False)):
        job = start_figure(str(tmp_path / (name + suffix)), child=child)
        job.send_unknown(*unknown)
        job.send_known(known)
        job.finish()
    child, here = (_comparable((tmp_path / (n + suffix)).read_bytes()) for n in ("child", "here"))
    assert child == here and len(child) > 10_000


def _comparable(data: bytes) -> bytes:
    """An image file less what differs from run to run: an SVG's date and random ids."""
    data = re.sub(rb"<dc:date>[^<]*</dc:date>", b"", data)
    return re.sub(rb'(id="|url\(#|href="#)[0-9a-zA-Z_]+', rb"\1ID", data)


def test_a_known_panel_that_needs_more_room_is_drawn_again(tmp_path: Path, paper_solution):
    (unknown, truth, poses), known = paper_solution
    longer = copy.deepcopy(known)
    longer.best.assignment = [a + "-a-long-name" for a in known.best.assignment]
    for name, child in (("child.png", True), ("here.png", False)):
        job = start_figure(str(tmp_path / name), child=child)
        job.send_unknown(unknown, truth, poses)
        job.send_known(longer)  # its title takes more lines than the survivors'
        job.finish()
    assert (tmp_path / "child.png").read_bytes() == (tmp_path / "here.png").read_bytes()
    builder = KnownUnknownFigure(unknown, truth, observation_poses=poses)
    height = builder.figure.get_size_inches()[1]
    assert not builder.add_known(longer) and builder.figure.get_size_inches()[1] > height
    builder = KnownUnknownFigure(unknown, truth, observation_poses=poses)
    assert builder.add_known(known)  # fits the room left for it


def test_a_child_that_cannot_write_names_the_file(tmp_path: Path, paper_solution) -> None:
    path = tmp_path / "gone" / "paper.png"  # the folder does not exist
    job = start_figure(str(path), child=True)
    job.send_unknown(None, None)  # no unknown-correspondence part: the known panel alone
    job.send_known(paper_solution[1])
    with pytest.raises(CommandError, match=r"gone/paper\.png: cannot write"):
        job.finish()
    assert not path.exists()


def test_a_child_stopped_after_the_first_part_writes_nothing(
    tmp_path: Path, paper_solution
) -> None:
    path = tmp_path / "paper.png"
    job = start_figure(str(path), child=True)
    job.send_unknown(*paper_solution[0])
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
