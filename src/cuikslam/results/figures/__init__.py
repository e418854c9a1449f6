"""Figures of guaranteed SLAM results: pose and landmark boxes, heading fans, the truth.

Two layers, as in GTSAM's ``gtsam.utils.plot``:

* ``*_on_axes`` functions (:mod:`.axes`) draw into a Matplotlib ``Axes`` you own, so you
  can compose them with your own plots (and with Codac or GTSAM figures);
* :func:`plot_solution` (:mod:`.figure`) builds a whole figure (one panel, or small
  multiples when several hypotheses survive), :func:`plot_known_and_unknown`
  (:mod:`.known_unknown`) a log solved with and without its landmark ids side by side
  (``cuikslam paper``'s figure), and :func:`save_figure` writes either atomically.

:func:`build_page` and :func:`write_page` (:mod:`.page`, over the columns of
:mod:`.page_data`) make an interactive page of a result instead, one self-contained HTML
file (``cuikslam view``; Bokeh, imported only then: ``pip install "cuikslam[view]"``).

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
  black crosses (landmarks): the poses the hypothesis has, and the true landmarks its
  landmarks stand for, paired through the association (an unknown-correspondence
  hypothesis names the landmarks it adds ``+1``, ``+2``, ... in order of first sighting,
  whatever the truth calls them). On a long run only the poses whose boxes are drawn get a
  dot and a tick; a thin line, the true path, runs through all of them.
* The envelope of an unknown-correspondence result (boxes that hold the truth whatever the
  correspondence, even when the search stopped on its budget) is drawn as light grey
  outlines under the hypotheses (:func:`plot_envelope_on_axes`), or alone, with where each
  sighted landmark lies, when the result has no hypothesis.
* Given the pose of each observation, the sightings (the kinematic graph's observation
  edges) are drawn as thin grey lines, in red where the survivors of a search disagree.
* Legends sit outside the plots; PNGs are written at :data:`DPI` (200) pixels per inch.
"""

from cuikslam.results.figures.artists import (
    ENVELOPE_COLOR,
    FAN_RADIUS,
    POSE_COLOR,
    TRUTH_COLOR,
    class_color_map,
)
from cuikslam.results.figures.axes import (
    MAX_SIGHTINGS,
    WIDTH_BINS,
    plot_comparison_on_axes,
    plot_hypothesis_on_axes,
    plot_widths_on_axes,
)
from cuikslam.results.figures.envelope import plot_envelope_on_axes
from cuikslam.results.figures.figure import DPI, WIDTH_PANEL_POSES, plot_solution, save_figure
from cuikslam.results.figures.geometry import (
    MAX_POSE_BOXES,
    Extent,
    drawn_poses,
    pose_widths,
    scene_extent,
    spread_labels,
)
from cuikslam.results.figures.known_unknown import KnownUnknownFigure, plot_known_and_unknown
from cuikslam.results.figures.page import BokehMissingError, build_page, write_page

__all__ = [
    "DPI",
    "ENVELOPE_COLOR",
    "FAN_RADIUS",
    "MAX_POSE_BOXES",
    "MAX_SIGHTINGS",
    "POSE_COLOR",
    "TRUTH_COLOR",
    "WIDTH_BINS",
    "WIDTH_PANEL_POSES",
    "BokehMissingError",
    "Extent",
    "KnownUnknownFigure",
    "build_page",
    "class_color_map",
    "drawn_poses",
    "plot_comparison_on_axes",
    "plot_envelope_on_axes",
    "plot_hypothesis_on_axes",
    "plot_known_and_unknown",
    "plot_solution",
    "plot_widths_on_axes",
    "pose_widths",
    "save_figure",
    "scene_extent",
    "spread_labels",
    "write_page",
]
