"""A figure drawn in a second process while the command goes on.

Importing Matplotlib, drawing and saving a figure takes most of a second, about a quarter
of a warm ``cuikslam paper``. The command starts ``python -m cuikslam.cli.figure_job PATH``
first, which imports Matplotlib while the parent solves the known-correspondence part (no
time budget binds there), then hands it that result (pickled, on its stdin); the child
draws and saves while the parent starts the second part, and the parent waits for it at
the end. The child is done before the second part's witness search, whose time budget
binds, so it does not take that search's time. It is used only when a core looks free
(:func:`spare_core`); otherwise, or where no process can be started, the figure is drawn
in-process, as before.
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
    from cuikslam.results.solution import Solution
    from cuikslam.simulate.truth import GroundTruth

__all__ = ["FigureJob", "spare_core", "start_figure"]

_CANNOT_WRITE = 3
"""The child's exit status when the figure file could not be written (an OSError)."""


@dataclass
class FigureJob:
    """A figure to draw into ``path``: by ``process`` (None: here, when finishing)."""

    path: str
    process: subprocess.Popen[bytes] | None
    drawn: tuple[Solution, GroundTruth | None] | None = None

    def send(self, solution: Solution, truth: GroundTruth | None) -> None:
        """Hand over what to draw (the child has been importing Matplotlib meanwhile).

        The payload (a few kB for the seed's experiment) fits in the pipe's buffer, so this
        does not wait for the child."""
        self.drawn = (solution, truth)
        if self.process is not None:
            assert self.process.stdin is not None
            try:
                self.process.stdin.write(pickle.dumps((solution, truth)))
                self.process.stdin.close()
            except OSError:  # the child died: draw here
                self.cancel()

    def cancel(self) -> None:
        """Stop the child without a figure (nothing to draw after all)."""
        if self.process is not None:
            self.process.kill()
            self.process.wait()
            self.process = None

    def finish(self) -> None:
        """Wait for the figure to be written (after :meth:`send`).

        Raises
        ------
        CommandError
            When the file could not be written (naming it, as :func:`write_output` does).
        RuntimeError
            When drawing failed otherwise (a bug: the child's traceback is in the message).
        """
        if self.process is None:
            assert self.drawn is not None, "send() first"
            _draw_here(*self.drawn, self.path)
            return
        assert self.process.stderr is not None  # stdout is not read: no deadlock
        message = self.process.stderr.read().decode(errors="replace").strip()
        self.process.wait()
        if self.process.returncode == _CANNOT_WRITE:
            raise CommandError(f"{self.path}: cannot write: {message}")
        if self.process.returncode != 0:
            raise RuntimeError(f"drawing {self.path} failed:\n{message}")


def _draw_here(solution: Solution, truth: GroundTruth | None, path: str) -> None:
    from cuikslam.results.figures import plot_solution, save_figure

    drawing = plot_solution(solution, truth)
    write_output(path, lambda: save_figure(drawing, path))


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
        machine it takes the parent's time (0.2 s slower at load 4 on two cores, see
        ``docs/benchmarks.md``); on a free core it can save at most the figure's own
        time (0.8 s at load 5), which could not be measured on the busy machine.

    Returns
    -------
    FigureJob
        Call :meth:`~FigureJob.send`, then :meth:`~FigureJob.finish` before reporting the
        figure written (or :meth:`~FigureJob.cancel`).
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

    from cuikslam.results.figures import plot_solution, save_figure

    payload = sys.stdin.buffer.read()
    if not payload:  # the parent stopped without sending anything
        return 0
    solution, truth = pickle.loads(payload)
    drawing = plot_solution(solution, truth)
    try:
        save_figure(drawing, path)
    except OSError as err:
        print(err.strerror or err, file=sys.stderr)
        return _CANNOT_WRITE
    return 0


if __name__ == "__main__":
    status = _main(sys.argv[1])
    sys.stderr.flush()
    os._exit(status)  # skips finalising the interpreter (nothing is left to write)
