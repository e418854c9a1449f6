"""The figure of ``cuikslam paper`` drawn in a second process while the command goes on.

The figure (:func:`~cuikslam.results.figures.plot_known_and_unknown`) shows both parts of
the command: the known-correspondence solve beside the survivors of the
unknown-correspondence one. The command starts ``python -m cuikslam.cli.figure_job PATH``
first, which imports Matplotlib (about half a second) while the parent solves. The parent
solves the unknown-correspondence part first and hands its result over (pickled, on the
child's stdin); while the parent solves the known part, the child lays the figure out and
draws every panel but the known one (:class:`~cuikslam.results.figures.
KnownUnknownFigure`). When the known result comes, the child draws only its panel onto
that canvas and writes the PNG, while the parent prints its tables; the parent waits for
it at the end. (When the known panel changes the layout, or for a PDF or SVG, the child
draws the whole figure again: the same figure, slower.) It is used only when a core looks
free (:func:`spare_core`); otherwise, or where no process can be started, the figure is
drawn in-process, at the end.
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

    from cuikslam.outcome.solution import Solution
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
    unknown: tuple[Solution | None, GroundTruth | None, list[int] | None] | None = None
    known: Solution | None = None

    def send_unknown(
        self,
        solution: Solution | None,
        truth: GroundTruth | None,
        observation_poses: list[int] | None = None,
    ) -> None:
        """Hand over the unknown-correspondence result (None: none), the truth and the
        pose of each observation, first: the child draws the survivors' panels while the
        parent solves the known part.

        The payloads (a few kB for the seed's experiment) fit in the pipe's buffer, so
        sending does not wait for the child."""
        self.unknown = (solution, truth, observation_poses)
        self._write(self.unknown)

    def send_known(self, solution: Solution) -> None:
        """Hand over the known-correspondence result, after :meth:`send_unknown`; the
        child then draws its panel and saves the figure."""
        self.known = solution
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
        """Wait for the figure to be written (after :meth:`send_unknown` and
        :meth:`send_known`).

        Raises
        ------
        CommandError
            When the file could not be written (naming it, as :func:`write_output` does).
        RuntimeError
            When drawing failed otherwise (a bug: the child's traceback is in the message).
        """
        if self.process is None:
            assert self.unknown is not None and self.known is not None, "send both first"
            _draw_here(*self.unknown, self.known, self.path)
            return
        assert self.process.stderr is not None  # stdout is not read: no deadlock
        message = self.process.stderr.read().decode(errors="replace").strip()
        self.process.wait()
        if self.process.returncode == _CANNOT_WRITE:
            raise CommandError(f"{self.path}: cannot write: {message}")
        if self.process.returncode != 0:
            raise RuntimeError(f"drawing {self.path} failed:\n{message}")


def _draw_here(
    unknown: Solution | None,
    truth: GroundTruth | None,
    observation_poses: list[int] | None,
    known: Solution,
    path: str,
) -> None:
    from cuikslam.results.figures import plot_known_and_unknown, save_figure

    drawing = plot_known_and_unknown(
        known, unknown, truth, observation_poses=observation_poses, dpi=PAPER_DPI
    )
    write_output(path, lambda: save_figure(drawing, path, PAPER_DPI, tight=False))


def spare_core() -> bool:
    """Whether a core looks free for a second process: the 1-minute load average (this
    process included) is below the number of cores minus a half."""
    try:
        return os.getloadavg()[0] < (os.cpu_count() or 1) - 0.5
    except (AttributeError, OSError):  # no load average on this system
        return False


def start_figure(path: str, *, child: bool | None = None) -> FigureJob:
    """Start a process that imports Matplotlib, then draws what :class:`FigureJob` sends.

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
        Call :meth:`~FigureJob.send_unknown`, :meth:`~FigureJob.send_known`, then
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

    from cuikslam.results.figures import KnownUnknownFigure, plot_known_and_unknown, save_figure

    stream = sys.stdin.buffer
    try:
        unknown, truth, observation_poses = pickle.load(stream)
    except EOFError:  # the parent stopped without sending anything
        return 0
    png = path.lower().endswith(".png")
    builder = None
    if unknown is not None:  # every panel but the known one, while the parent solves it
        builder = KnownUnknownFigure(
            unknown, truth, observation_poses=observation_poses, dpi=PAPER_DPI
        )
        if png:
            builder.figure.canvas.draw()
    try:
        known = pickle.load(stream)
    except EOFError:  # the parent stopped before the known part: no figure
        return 0
    try:
        if builder is None:
            figure = plot_known_and_unknown(
                known, None, truth, observation_poses=observation_poses, dpi=PAPER_DPI
            )
            save_figure(figure, path, PAPER_DPI, tight=False)
        elif builder.add_known(known) and png:
            builder.figure.draw_artist(builder.known_axes)  # onto the canvas drawn above
            _write_drawn_png(builder.figure, path)
        else:  # a vector format, or the known panel moved the rest: draw it all
            save_figure(builder.figure, path, PAPER_DPI, tight=False)
    except OSError as err:
        print(err.strerror or err, file=sys.stderr)
        return _CANNOT_WRITE
    return 0


def _write_drawn_png(figure: Figure, path: str) -> None:
    """Write the canvas as drawn (no new drawing pass), atomically, as
    :func:`~cuikslam.results.figures.save_figure` would (the same bytes)."""
    from matplotlib.image import imsave

    from cuikslam._atomic import atomic_open
    from cuikslam.results.figures.figure import PNG_COMPRESS_LEVEL

    with atomic_open(path, "wb") as stream:
        imsave(
            stream,
            figure.canvas.buffer_rgba(),
            format="png",
            origin="upper",
            dpi=figure.dpi,
            pil_kwargs={"compress_level": PNG_COMPRESS_LEVEL},
        )


if __name__ == "__main__":
    status = _main(sys.argv[1])
    sys.stderr.flush()
    os._exit(status)  # skips finalising the interpreter (nothing is left to write)
