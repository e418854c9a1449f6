"""Figures of guaranteed SLAM results: pose and landmark boxes, heading fans, the truth.

Two layers, as in GTSAM's ``gtsam.utils.plot``:

* ``*_on_axes`` functions (:mod:`.axes`) draw into a Matplotlib ``Axes`` you own, so you
  can compose them with your own plots (and with Codac or GTSAM figures);
* :func:`plot_solution` (:mod:`.figure`) builds a whole figure (one panel, or small
  multiples when several hypotheses survive), and :func:`save_figure` writes it
  atomically.

Under them, :mod:`.geometry` holds what needs no Matplotlib (extents, clipping, which
boxes a long run draws, widths) and :mod:`.artists` the drawing primitives (colours,
rectangles, the truth's markers, legends). Every name below is importable from here.

Matplotlib is imported inside the functions only, never when this module is imported, and
nothing here calls ``plt.show()``: the functions work under the non-interactive ``Agg``
backend (servers, CI).  Figures are created through :mod:`matplotlib.pyplot`, so a
script may still call ``plt.show()`` itself.

Drawing conventions
-------------------
* A pose box is an unfilled rectangle ``x × y`` plus a *heading fan*: a wedge from the box
  centre spanning the heading interval (θ counter-clockwise from +x).  A heading interval
  at least 2π wide (or unbounded) means "any heading" and is drawn as a full disc.
* Landmark boxes are filled rectangles coloured by landmark class.
* Unbounded (±inf) bounds are clipped to the scene extent and the box is drawn dashed.
* The truth, when given, is drawn as black dots with a short heading tick (poses) and
  black crosses (landmarks); only poses and landmarks whose ids the hypothesis has are
  drawn, since a wrong hypothesis may use the same landmark ids for other landmarks.
"""

from cuikslam.results.figures.artists import (
    FAN_RADIUS,
    POSE_COLOR,
    TRUTH_COLOR,
    class_color_map,
)
from cuikslam.results.figures.axes import (
    WIDTH_BINS,
    plot_comparison_on_axes,
    plot_hypothesis_on_axes,
    plot_widths_on_axes,
)
from cuikslam.results.figures.figure import WIDTH_PANEL_POSES, plot_solution, save_figure
from cuikslam.results.figures.geometry import (
    MAX_POSE_BOXES,
    Extent,
    drawn_poses,
    pose_widths,
    scene_extent,
)

__all__ = [
    "FAN_RADIUS",
    "MAX_POSE_BOXES",
    "POSE_COLOR",
    "TRUTH_COLOR",
    "WIDTH_BINS",
    "WIDTH_PANEL_POSES",
    "Extent",
    "class_color_map",
    "drawn_poses",
    "plot_comparison_on_axes",
    "plot_hypothesis_on_axes",
    "plot_solution",
    "plot_widths_on_axes",
    "pose_widths",
    "save_figure",
    "scene_extent",
]
