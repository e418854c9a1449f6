"""Figures: artists per kind, shared limits, unbounded boxes, atomic saving, lazy import."""

from __future__ import annotations

import copy
import math
import os
import struct
import subprocess
import sys
import textwrap

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.patches import Rectangle, Wedge

from cuikslam.results.figures import (
    MAX_POSE_BOXES,
    class_color_map,
    drawn_poses,
    plot_comparison_on_axes,
    plot_hypothesis_on_axes,
    plot_solution,
    plot_widths_on_axes,
    pose_widths,
    save_figure,
    scene_extent,
)
from cuikslam.results.solution import PROVEN, Hypothesis, Solution
from cuikslam.simulate.truth import GroundTruth

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def make_hypothesis() -> Hypothesis:
    """Three poses on a line, two landmarks of two classes."""
    poses = np.array(
        [
            [[-0.1, 0.1], [-0.1, 0.1], [0.0, 0.0]],  # exact heading: a zero-width fan
            [[4.5, 5.5], [-0.5, 0.5], [-0.2, 0.3]],
            [[9.0, 11.0], [-1.0, 1.0], [0.1, 0.1 + 2 * math.pi]],  # any heading
        ]
    )
    landmarks = np.array([[[4.0, 6.0], [4.0, 6.0]], [[9.5, 10.5], [-6.0, -4.0]]])
    return Hypothesis(
        assignment=["L1", "L2", "L1", "L2"],
        pose_ids=[0, 1, 2],
        poses=poses,
        landmark_ids=["L1", "L2"],
        landmark_classes=["door", "tree"],
        landmarks=landmarks,
    )


def make_truth() -> GroundTruth:
    return GroundTruth(
        poses_xyt=np.array([[0.0, 0.0, 0.0], [5.0, 0.0, 0.1], [10.0, 0.0, 0.2]]),
        pose_ids=[0, 1, 2],
        landmarks_xy=np.array([[5.0, 5.0], [10.0, -5.0], [20.0, 20.0]]),
        landmark_ids=["L1", "L2", "L9"],  # L9 is not in the hypothesis: not drawn
        landmark_classes=["door", "tree", "door"],
        assignment=["L1", "L2", "L1", "L2"],
    )


def make_solution(n: int, *, complete: bool = True) -> Solution:
    hypotheses = []
    for k in range(n):
        h = copy.deepcopy(make_hypothesis())
        h.landmarks = h.landmarks + k  # distinct boxes per hypothesis
        h.assignment = list(np.roll(h.assignment, k))
        if k == 1:
            h.status = PROVEN
        hypotheses.append(h)
    return Solution(hypotheses=hypotheses, complete=complete, statistics={"candidates": 4 * n})


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def png_size(path) -> tuple[int, int]:
    with open(path, "rb") as stream:
        head = stream.read(24)
    assert head[:8] == PNG_MAGIC
    return struct.unpack(">II", head[16:24])


def visible_axes(fig) -> list:
    return [ax for ax in fig.axes if ax.get_visible()]


# --------------------------------------------------------------------------- axes layer
def test_hypothesis_on_axes_draws_each_kind():
    _, ax = plt.subplots()
    drawn = plot_hypothesis_on_axes(ax, make_hypothesis(), make_truth(), title="t")
    counts = {kind: len(artists) for kind, artists in drawn.items()}
    assert counts == {
        "pose_boxes": 3,
        "heading_fans": 3,
        "pose_labels": 3,
        "path": 1,
        "landmark_boxes": 2,
        "landmark_labels": 2,
        "sightings": 0,  # no observation_poses given
        "ambiguous_sightings": 0,
        "truth_poses": 1,
        "truth_headings": 1,
        "truth_path": 0,  # every pose drawn: no thinned true path
        "truth_landmarks": 1,
        "legend": 1,
    }
    assert all(isinstance(p, Rectangle) for p in drawn["pose_boxes"] + drawn["landmark_boxes"])
    assert all(isinstance(w, Wedge) for w in drawn["heading_fans"])
    assert len([p for p in ax.patches if isinstance(p, Rectangle)]) == 5
    # Pose boxes as given, fans from the box centres, the path through them.
    first = drawn["pose_boxes"][1]
    assert (first.get_x(), first.get_y(), first.get_width(), first.get_height()) == pytest.approx(
        (4.5, -0.5, 1.0, 1.0)
    )
    assert drawn["heading_fans"][1].center == pytest.approx((5.0, 0.0))
    assert drawn["heading_fans"][1].theta1 == pytest.approx(math.degrees(-0.2))
    assert drawn["heading_fans"][1].theta2 == pytest.approx(math.degrees(0.3))
    assert drawn["heading_fans"][2].theta2 - drawn["heading_fans"][2].theta1 == 360
    path_x, path_y = drawn["path"][0].get_data()
    assert list(path_x) == pytest.approx([0.0, 5.0, 10.0])
    assert list(path_y) == pytest.approx([0.0, 0.0, 0.0])
    # Labels, classes in the legend, the truth filtered by the hypothesis' ids.
    assert [t.get_text() for t in drawn["pose_labels"]] == ["0", "1", "2"]
    assert [t.get_text() for t in drawn["landmark_labels"]] == ["L1", "L2"]
    legend_texts = [t.get_text() for t in drawn["legend"][0].get_texts()]
    assert "landmark: door" in legend_texts and "landmark: tree" in legend_texts
    assert "true landmark" in legend_texts
    assert len(drawn["truth_landmarks"][0].get_xdata()) == 2
    assert len(drawn["truth_poses"][0].get_xdata()) == 3
    assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    assert ax.get_aspect() == 1.0
    assert ax.get_title() == "t"


def test_landmark_colours_follow_classes():
    h = make_hypothesis()
    h.landmarks = np.concatenate([h.landmarks, h.landmarks + 20.0])
    h.landmark_ids = ["L1", "L2", "L3", "L4"]
    h.landmark_classes = ["door", "tree", "door", "tree"]
    _, ax = plt.subplots()
    boxes = plot_hypothesis_on_axes(ax, h)["landmark_boxes"]
    colours = [tuple(b.get_facecolor()) for b in boxes]
    assert colours[0] == colours[2] and colours[1] == colours[3]
    assert colours[0] != colours[1]


def test_class_color_map_is_stable_and_distinct():
    a = class_color_map(["tree", "door", "corridor", "door"])
    b = class_color_map(["corridor", "tree", "door"])
    assert a == b
    assert len(set(a.values())) == 3
    many = class_color_map(f"c{i}" for i in range(40))
    assert len(many) == 40


def test_options_switch_off_labels_fans_and_legend():
    _, ax = plt.subplots()
    drawn = plot_hypothesis_on_axes(
        ax, make_hypothesis(), show_labels=False, heading_fan=False, legend=False
    )
    assert drawn["pose_labels"] == drawn["landmark_labels"] == drawn["heading_fans"] == []
    assert drawn["legend"] == [] and ax.get_legend() is None
    assert drawn["truth_poses"] == []
    assert len(drawn["pose_boxes"]) == 3


def test_empty_heading_interval_has_no_fan():
    h = make_hypothesis()
    h.poses[1, 2] = [0.5, 0.1]
    _, ax = plt.subplots()
    assert len(plot_hypothesis_on_axes(ax, h)["heading_fans"]) == 2


def test_infinite_bounds_are_clipped_and_dashed(tmp_path):
    h = make_hypothesis()
    h.poses[1, 0, 1] = np.inf
    h.poses[1, 2] = [-np.inf, np.inf]
    h.landmarks[1, 1, 0] = -np.inf
    fig, ax = plt.subplots()
    drawn = plot_hypothesis_on_axes(ax, h, make_truth())
    x_lo, x_hi = ax.get_xlim()
    y_lo, y_hi = ax.get_ylim()
    for rect in drawn["pose_boxes"] + drawn["landmark_boxes"]:
        corners = rect.get_bbox().get_points()
        assert np.isfinite(corners).all()
        assert x_lo <= corners[0, 0] <= corners[1, 0] <= x_hi
        assert y_lo <= corners[0, 1] <= corners[1, 1] <= y_hi
    styles = [r.get_linestyle() for r in drawn["pose_boxes"]]
    assert styles == ["-", "--", "-"]
    assert drawn["landmark_boxes"][1].get_linestyle() == "--"
    assert drawn["landmark_boxes"][0].get_linestyle() == "-"
    assert drawn["heading_fans"][1].theta2 - drawn["heading_fans"][1].theta1 == 360
    assert "unbounded (clipped)" in [t.get_text() for t in drawn["legend"][0].get_texts()]
    save_figure(fig, tmp_path / "inf.png")
    assert (tmp_path / "inf.png").stat().st_size > 0


def test_all_bounds_infinite_falls_back_to_a_default_extent(tmp_path):
    h = make_hypothesis()
    h.poses[:, :2] = [-np.inf, np.inf]
    h.landmarks[:] = [-np.inf, np.inf]
    assert scene_extent([h.poses, h.landmarks]) == pytest.approx((-1.12, 1.12, -1.12, 1.12))
    save_figure(plot_solution(Solution([h])), tmp_path / "all_inf.png")
    assert (tmp_path / "all_inf.png").stat().st_size > 0


def test_empty_landmark_list(tmp_path):
    h = make_hypothesis()
    h.landmarks = np.empty((0, 2, 2))
    h.landmark_ids, h.landmark_classes, h.assignment = [], [], []
    _, ax = plt.subplots()
    drawn = plot_hypothesis_on_axes(ax, h, make_truth())
    assert drawn["landmark_boxes"] == drawn["landmark_labels"] == []
    assert drawn["truth_landmarks"] == []  # no landmark id of the truth is in the hypothesis
    assert len(drawn["pose_boxes"]) == 3
    figure = plot_solution(Solution([h]), make_truth())
    assert "no observations" in visible_axes(figure)[0].get_title()
    save_figure(figure, tmp_path / "no_landmarks.png")
    assert (tmp_path / "no_landmarks.png").stat().st_size > 0


def test_comparison_overlays_labelled_sets():
    outer = make_hypothesis().poses
    inner = outer.copy()
    inner[..., 0] += 0.1
    inner[..., 1] -= 0.1
    inner[2, 0, 1] = np.inf
    _, ax = plt.subplots()
    drawn = plot_comparison_on_axes(
        ax, {"outer": outer, "inner": inner[:, :2]}, make_truth(), title="levels"
    )
    assert len(drawn["outer"]) == 3 and len(drawn["inner"]) == 3
    assert drawn["outer"][0].get_edgecolor() != drawn["inner"][0].get_edgecolor()
    assert drawn["inner"][2].get_linestyle() == "--"
    texts = [t.get_text() for t in drawn["legend"][0].get_texts()]
    assert texts[:2] == ["outer", "inner"]
    assert "unbounded (clipped)" in texts
    assert len(drawn["truth_poses"][0].get_xdata()) == 3
    assert len(drawn["truth_landmarks"][0].get_xdata()) == 3  # all truth landmarks
    with pytest.raises(ValueError, match="shape"):
        plot_comparison_on_axes(ax, {"bad": np.zeros((3, 2))})


# --------------------------------------------------------------------------- figure layer
def test_known_correspondence_is_titled_as_such():
    solution = make_solution(1)
    solution.statistics = {"poses": 3, "landmarks": 2}  # no correspondence search ran
    fig = plot_solution(solution, make_truth())
    assert fig.get_suptitle().startswith("known correspondence · level ")


def test_solution_with_one_hypothesis(tmp_path):
    fig = plot_solution(make_solution(1), make_truth())
    axes = visible_axes(fig)
    assert len(axes) == 1
    rects = [p for p in axes[0].patches if isinstance(p, Rectangle)]
    assert len(rects) == 5  # 3 poses + 2 landmarks
    assert fig.get_suptitle() == "1 hypothesis survived · search complete"
    title = axes[0].get_title()
    assert title.startswith("#1 · 2 landmarks · not refuted")
    assert "obs→L: 1 2 1 2" in title
    path = tmp_path / "one.png"
    save_figure(fig, path)
    width, height = png_size(path)
    assert 600 <= width <= 3000 and 500 <= height <= 3000
    assert 5_000 < path.stat().st_size < 3_000_000
    assert os.listdir(tmp_path) == ["one.png"]
    assert not plt.fignum_exists(fig.number)


def test_solution_small_multiples_share_limits(tmp_path):
    solution = make_solution(5)
    fig = plot_solution(solution, make_truth())
    axes = visible_axes(fig)
    assert len(axes) == 5
    assert len(fig.axes) == 6  # a 3 × 2 grid, the last cell hidden
    for ax in axes:
        assert len([p for p in ax.patches if isinstance(p, Rectangle)]) == 5
        assert len([p for p in ax.patches if isinstance(p, Wedge)]) == 3
        assert ax.get_xlim() == axes[0].get_xlim()
        assert ax.get_ylim() == axes[0].get_ylim()
    titles = [ax.get_title() for ax in axes]
    assert [t.split(" ·")[0] for t in titles] == ["#1", "#2", "#3", "#4", "#5"]
    assert "proven consistent" in titles[1]
    assert "obs→L: 2 1 2 1" in titles[1]
    assert fig.get_suptitle() == "5 hypotheses survived · search complete"
    assert len(fig.legends) == 1
    # The shared limits contain every panel's boxes.
    x_lo, x_hi = axes[0].get_xlim()
    y_lo, y_hi = axes[0].get_ylim()
    for h in solution.hypotheses:
        assert x_lo <= h.landmarks[:, 0].min() and h.landmarks[:, 0].max() <= x_hi
        assert y_lo <= h.landmarks[:, 1].min() and h.landmarks[:, 1].max() <= y_hi
    path = tmp_path / "five.png"
    save_figure(fig, path)
    assert 10_000 < path.stat().st_size < 5_000_000
    assert os.listdir(tmp_path) == ["five.png"]


def test_truncated_incomplete_solution_says_so():
    fig = plot_solution(make_solution(5, complete=False), max_hypotheses=3)
    assert len(visible_axes(fig)) == 3
    suptitle = fig.get_suptitle()
    assert "5 hypotheses" in suptitle
    assert "+2 more not shown" in suptitle
    assert "INCOMPLETE" in suptitle
    with pytest.raises(ValueError, match="max_hypotheses"):
        plot_solution(make_solution(2), max_hypotheses=0)


def test_no_hypothesis_gives_a_message_panel():
    fig = plot_solution(Solution([], complete=True), make_truth())
    assert "no hypothesis survived" in fig.get_suptitle()
    assert "proven inconsistent" in fig.get_suptitle()
    texts = [t.get_text() for t in visible_axes(fig)[0].texts]
    assert texts == ["nothing to draw: the log was refuted"]


def test_long_assignment_is_wrapped_and_shortened():
    h = make_hypothesis()
    h.assignment = [f"L{i % 2 + 1}" for i in range(300)]
    fig = plot_solution(Solution([h, h]))
    title = visible_axes(fig)[0].get_title()
    lines = title.split("\n")
    assert len(lines) == 4  # the heading and at most 3 lines of assignment
    assert lines[-1].endswith("…")
    assert max(len(line) for line in lines) <= 50


def test_assignment_without_common_prefix_keeps_ids():
    h = make_hypothesis()
    h.landmark_ids = ["A", "B"]
    h.assignment = ["A", "B", "A"]
    fig = plot_solution(Solution([h]))
    assert "obs→landmark: A B A" in visible_axes(fig)[0].get_title()


# --------------------------------------------------------------------------- saving
@pytest.mark.parametrize(("suffix", "magic"), [(".pdf", b"%PDF"), (".svg", b"<?xml")])
def test_save_other_formats(tmp_path, suffix, magic):
    path = tmp_path / f"figure{suffix}"
    save_figure(plot_solution(make_solution(2)), path)
    assert path.read_bytes().startswith(magic)
    assert os.listdir(tmp_path) == [path.name]


def test_save_rejects_unknown_suffix(tmp_path):
    fig = plot_solution(make_solution(1))
    with pytest.raises(ValueError, match="png"):
        save_figure(fig, tmp_path / "figure.jpeg")
    assert os.listdir(tmp_path) == []
    assert plt.fignum_exists(fig.number)  # left open for another try


def test_failed_save_leaves_old_file_and_no_temporary(tmp_path, monkeypatch):
    path = tmp_path / "figure.png"
    path.write_bytes(b"old")
    fig = plot_solution(make_solution(1))

    def broken_savefig(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(fig, "savefig", broken_savefig)
    with pytest.raises(RuntimeError, match="disk full"):
        save_figure(fig, path)
    assert path.read_bytes() == b"old"
    assert os.listdir(tmp_path) == ["figure.png"]


def test_save_replaces_existing_file(tmp_path):
    path = tmp_path / "figure.png"
    path.write_bytes(b"old")
    save_figure(plot_solution(make_solution(1)), str(path))
    assert path.read_bytes().startswith(PNG_MAGIC)


# --------------------------------------------------------------------------- import
def test_import_does_not_load_matplotlib():
    code = textwrap.dedent(
        """
        import sys
        import cuikslam.results.figures
        assert "matplotlib.pyplot" not in sys.modules, "pyplot imported"
        assert "matplotlib" not in sys.modules, "matplotlib imported"
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120
    )
    assert result.returncode == 0, result.stderr


# --------------------------------------------------------------------------- long runs
def make_long_hypothesis(n: int) -> Hypothesis:
    """``n`` poses around a circle, boxes growing along the run; pose 2n/3 the widest."""
    k = np.arange(n)
    angle = 2 * math.pi * k / n
    half = 0.1 + 0.01 * k
    half[2 * n // 3] = 50.0
    centre = np.stack([20 * np.cos(angle), 20 * np.sin(angle)], axis=1)
    poses = np.empty((n, 3, 2))
    poses[:, :2, 0] = centre - half[:, None]
    poses[:, :2, 1] = centre + half[:, None]
    poses[:, 2] = np.stack([angle - half, angle + half], axis=1)
    poses[n // 2, 2] = (-math.inf, math.inf)  # an unknown heading
    poses[n // 3, 1, 1] = math.inf  # an unbounded side
    return Hypothesis(
        assignment=["L1"] * n,
        pose_ids=list(range(100, 100 + n)),
        poses=poses,
        landmark_ids=["L1"],
        landmark_classes=["door"],
        landmarks=np.array([[[-1.0, 1.0], [-1.0, 1.0]]]),
        consistency="hull",
    )


def test_drawn_poses_thin_long_runs_keeping_last_and_widest():
    h = make_long_hypothesis(1000)
    assert drawn_poses(h.poses, 2000).tolist() == list(range(1000))
    assert drawn_poses(h.poses, None).tolist() == list(range(1000))
    drawn = drawn_poses(h.poses, MAX_POSE_BOXES)
    assert len(drawn) <= MAX_POSE_BOXES
    assert len(drawn) >= MAX_POSE_BOXES // 2
    assert drawn[0] == 0 and drawn[-1] == 999
    assert 1000 // 3 in drawn  # the widest: its y side is unbounded
    assert np.all(np.diff(drawn) > 0)
    h.poses[1000 // 3, 1, 1] = h.poses[1000 // 3, 1, 0] + 1.0
    assert 2 * 1000 // 3 in drawn_poses(h.poses, MAX_POSE_BOXES)  # now the widest


def test_long_hypothesis_draws_every_nth_box_and_the_whole_path():
    h = make_long_hypothesis(1000)
    _fig, ax = plt.subplots()
    artists = plot_hypothesis_on_axes(ax, h)
    assert len(artists["pose_boxes"]) == len(drawn_poses(h.poses))
    assert len(artists["heading_fans"]) == len(artists["pose_boxes"])
    (path,) = artists["path"]
    assert len(path.get_xdata()) == 1000
    labels = [t.get_text() for t in artists["pose_labels"]]
    assert labels[0] == "100" and set(labels) <= {str(100 + i) for i in drawn_poses(h.poses)}
    every = plot_hypothesis_on_axes(ax, h, max_pose_boxes=None)
    assert len(every["pose_boxes"]) == 1000


def test_long_solution_gets_a_width_panel_and_a_short_title(tmp_path):
    n = 400
    h = make_long_hypothesis(n)
    fig = plot_solution(Solution([h], consistency="hull"))
    boxes_ax, widths_ax = visible_axes(fig)[:2]
    title = boxes_ax.get_title()
    assert len(title.split("\n")) == 2 and max(map(len, title.split("\n"))) <= 80
    assert "400 poses" in title and "400 observations" in title
    assert "L1 " not in title and "obs→" not in title
    assert widths_ax.get_xlabel() == "pose (in log order)"
    lines = widths_ax.get_lines()
    x_width = lines[0].get_ydata()
    assert len(x_width) == n
    assert x_width[0] == pytest.approx(0.2) and x_width[2 * n // 3] == pytest.approx(100.0)
    assert math.isnan(lines[1].get_ydata()[n // 3])  # unbounded: a gap, not a spike
    theta = next(ax for ax in fig.axes if ax.get_ylabel() == "θ width [rad]").get_lines()[0]
    assert theta.get_ydata()[n // 2] == pytest.approx(2 * math.pi)  # capped: any heading
    path = tmp_path / "long.png"
    save_figure(fig, path)
    assert png_size(path)[1] > png_size(path)[0]  # taller than wide: map over widths


def test_short_solution_has_no_width_panel():
    fig = plot_solution(Solution([make_hypothesis()]))
    assert len(fig.axes) == 1
    assert pose_widths(make_hypothesis())[2, 2] == pytest.approx(2 * math.pi)


def test_width_panel_of_a_very_long_run_shows_the_largest_width_per_bin():
    n = 1000  # bins of 2 poses
    h = make_long_hypothesis(n)
    _fig, ax = plt.subplots()
    drawn = plot_widths_on_axes(ax, h)
    x_line, y_line, theta_line = drawn["lines"]
    assert x_line.get_xdata().tolist() == list(range(0, n, 2))
    widths = pose_widths(h)
    assert x_line.get_ydata().tolist() == np.maximum(widths[0::2, 0], widths[1::2, 0]).tolist()
    assert math.isnan(y_line.get_ydata()[n // 3 // 2])  # the bin with an unbounded side
    assert theta_line.get_ydata()[n // 2 // 2] == 2 * math.pi
    assert ax.get_xlim() == (0, n - 1)


def test_long_solution_zooms_on_its_widest_stretch():
    from cuikslam.results.figures.geometry import ZOOM_POSES, widest_stretch

    n = 400
    h = make_long_hypothesis(n)
    part = widest_stretch(h)
    assert part.stop - part.start == ZOOM_POSES and part.start <= 2 * n // 3 < part.stop
    fig = plot_solution(Solution([h], consistency="hull"))
    (zoom,) = [ax for ax in fig.axes if ax.get_title().startswith("the widest stretch")]
    first, last = 100 + part.start, 100 + part.stop - 1
    assert zoom.get_title() == f"the widest stretch: poses {first}–{last}"
    boxes = [p for p in zoom.patches if isinstance(p, Rectangle)]
    assert len(boxes) == ZOOM_POSES + 1  # every pose box of the stretch, and the landmark
    # an unbounded pose counts as the widest finite one: the zoom still has boxes to show
    h.poses[:, :2] = np.where(np.arange(n)[:, None, None] == 7, [-np.inf, np.inf], h.poses[:, :2])
    assert widest_stretch(h).start <= 2 * n // 3 < widest_stretch(h).stop
