"""The figure of ``cuikslam paper`` drawn in a second process while the command goes on.

Importing Matplotlib takes about half a second of a warm ``cuikslam paper``. The figure
(:func:`~cuikslam.results.figures.plot_known_and_unknown`) shows both parts of the
command: the known-correspondence solve beside the survivors of the unknown-correspondence
one. The command starts ``python -m cuikslam.cli.figure_job PATH`` first, which imports
Matplotlib while the parent solves, then hands it each part's result as soon as it is
solved (pickled, on its stdin); with the second, the child draws the whole figure (its
layout fixed: one drawing pass) and saves it while the parent prints its tables, and the
parent waits for it at the end. Drawing the first part's panel ahead, while the parent
solves the second part, saved nothing measurable (the drawing pass is the cost, and it
needs every panel). It is used only when a core looks free (:func:`spare_core`);
otherwise, or where no process can be started, the figure is drawn in-process, at the end.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING

from cuikslam.cli._common import CommandError, write_output

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from cuikslam.results.solution import Solution
    from cuikslam.simulate.truth import GroundTruth

__all__ = ["FigureJob", "spare_core", "start_figure"]

_CANNOT_WRITE = 3
"""The child's exit status when the figure file could not be written (an OSError)."""
PAPER_DPI = 150
"""Pixels per inch of the figure: it is 11 inches wide with two survivors (1,680 pixels,
240 per inch at a page's 7 inches); drawing it at the library's 200 would add a fifth to
the drawing the command waits for."""


@dataclass
class FigureJob:
    """A figure to draw into ``path``: by ``process`` (None: here, when finishing)."""

    path: str
    process: subprocess.Popen[bytes] | None
    known: tuple[Solution, GroundTruth | None, list[int] | None] | None = None
    unknown: Solution | None = None

    def send(
        self,
        solution: Solution,
        truth: GroundTruth | None,
        observation_poses: list[int] | None = None,
    ) -> None:
        """Hand over the known-correspondence result, its truth and the pose of each
        observation (the child has been importing Matplotlib meanwhile).

        The payloads (a few kB for the seed's experiment) fit in the pipe's buffer, so
        sending does not wait for the child."""
        self.known = (solution, truth, observation_poses)
        self._write(self.known)

    def send_unknown(self, solution: Solution | None) -> None:
        """Hand over the unknown-correspondence result (None: none), after :meth:`send`;
        the child then draws and saves the whole figure."""
        self.unknown = solution
        self._write(solution)
        if self.process is not None and self.process.stdin is not None:
            self.process.stdin.close()

    def _write(self, payload: object) -> None:
        if self.process is not None:
            assert self.process.stdin is not None
            try:
                self.process.stdin.write(pickle.dumps(payload))
                self.process.stdin.flush()
            except OSError:  # the child died: draw here
                self.cancel()

    def cancel(self) -> None:
        """Stop the child without a figure (nothing to draw after all)."""
        if self.process is not None:
            self.process.kill()
            self.process.wait()
            self.process = None

    def finish(self) -> None:
        """Wait for the figure to be written (after :meth:`send` and :meth:`send_unknown`).

        Raises
        ------
        CommandError
            When the file could not be written (naming it, as :func:`write_output` does).
        RuntimeError
            When drawing failed otherwise (a bug: the child's traceback is in the message).
        """
        if self.process is None:
            assert self.known is not None, "send() first"
            _draw_here(*self.known, self.unknown, self.path)
            return
        assert self.process.stderr is not None  # stdout is not read: no deadlock
        message = self.process.stderr.read().decode(errors="replace").strip()
        self.process.wait()
        if self.process.returncode == _CANNOT_WRITE:
            raise CommandError(f"{self.path}: cannot write: {message}")
        if self.process.returncode != 0:
            raise RuntimeError(f"drawing {self.path} failed:\n{message}")


def _figure(
    known: Solution,
    truth: GroundTruth | None,
    observation_poses: list[int] | None,
    unknown: Solution | None,
) -> Figure:
    from cuikslam.results.figures import plot_known_and_unknown

    return plot_known_and_unknown(known, unknown, truth, observation_poses=observation_poses)


def _draw_here(
    known: Solution,
    truth: GroundTruth | None,
    observation_poses: list[int] | None,
    unknown: Solution | None,
    path: str,
) -> None:
    from cuikslam.results.figures import save_figure

    drawing = _figure(known, truth, observation_poses, unknown)
    write_output(path, lambda: save_figure(drawing, path, PAPER_DPI, tight=False))


def spare_core() -> bool:
    """Whether a core looks free for a second process: the 1-minute load average (this
    process included) is below the number of cores minus a half."""
    try:
        return os.getloadavg()[0] < (os.cpu_count() or 1) - 0.5
    except (AttributeError, OSError):  # no load average on this system
        return False


def start_figure(path: str, *, child: bool | None = None) -> FigureJob:
    """Start a process that imports Matplotlib, then draws what :meth:`FigureJob.send` gives.

    Parameters
    ----------
    path : str
        The figure file (already checked by :func:`~cuikslam.cli._common.check_figure_path`).
    child : bool, optional
        Draw in a second process (True) or here when finishing (False). By default a
        second process only when a core looks free (:func:`spare_core`): on a busy
        machine it takes the parent's time (0.2 s slower at load 4 on two cores, see the
        README); on a free core it can save at most the figure's own time (0.8 s at load
        5), which could not be measured on the busy machine.

    Returns
    -------
    FigureJob
        Call :meth:`~FigureJob.send`, :meth:`~FigureJob.send_unknown`, then
        :meth:`~FigureJob.finish` before reporting the figure written (or
        :meth:`~FigureJob.cancel`).
    """
    path = os.fspath(path)
    if not (spare_core() if child is None else child):
        return FigureJob(path, None)
    try:
        process = subprocess.Popen(
            [sys.executable, "-m", "cuikslam.cli.figure_job", path],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
        )
    except OSError:
        return FigureJob(path, None)
    return FigureJob(path, process)


def _main(path: str) -> int:
    import matplotlib.pyplot  # noqa: F401  (imported while the parent solves)

    from cuikslam.results.figures import save_figure

    stream = sys.stdin.buffer
    try:
        known = pickle.load(stream)
    except EOFError:  # the parent stopped without sending anything
        return 0
    try:
        unknown = pickle.load(stream)
    except EOFError:  # the parent stopped before the second part: no figure
        return 0
    drawing = _figure(*known, unknown)
    try:
        save_figure(drawing, path, PAPER_DPI, tight=False)
    except OSError as err:
        print(err.strerror or err, file=sys.stderr)
        return _CANNOT_WRITE
    return 0


if __name__ == "__main__":
    status = _main(sys.argv[1])
    sys.stderr.flush()
    os._exit(status)  # skips finalising the interpreter (nothing is left to write)
