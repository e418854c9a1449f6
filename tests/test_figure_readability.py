"""Figures a person reads: the truth paired by association, no stray text, the envelope,
legends off the data, labels that do not pile up, print resolution, and ``cuikslam
paper``'s figure of both solves (issue 30, items 2 and 5; the envelope of issue 28)."""

from __future__ import annotations

import copy
import itertools
import struct
import zlib

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.transforms import Bbox

from cuikslam.results.evaluate import evaluate
from cuikslam.results.evaluation_figure import plot_evaluation
from cuikslam.results.figures import (
    DPI,
    ENVELOPE_COLOR,
    MAX_POSE_BOXES,
    drawn_poses,
    plot_envelope_on_axes,
    plot_hypothesis_on_axes,
    plot_known_and_unknown,
    plot_solution,
    save_figure,
)
from cuikslam.results.solution import PROVEN, Envelope, Hypothesis, Solution
from cuikslam.simulate.truth import GroundTruth
from test_figures import make_hypothesis, make_long_hypothesis, make_truth


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


def renamed(h: Hypothesis, names: dict[str, str]) -> Hypothesis:
    """``h`` with its landmarks renamed (as a search names them: in order of sighting)."""
    out = copy.deepcopy(h)
    out.assignment = [names[a] for a in h.assignment]
    out.landmark_ids = [names[m] for m in h.landmark_ids]
    return out


def far_truth() -> GroundTruth:
    """``make_truth`` whose landmarks are called L13 and L15, with a third one, L1, that no
    observation sees, standing where a name-matching figure would look."""
    t = make_truth()
    return GroundTruth(
        t.poses_xyt, t.pose_ids, np.array([[5.0, 5.0], [10.0, -5.0], [-30.0, 40.0]]),
        ["L13", "L15", "L1"], ["door", "tree", "door"], ["L13", "L15", "L13", "L15"],
    )  # fmt: skip


def circle_truth(h: Hypothesis) -> GroundTruth:
    """The truth of ``make_long_hypothesis``: its box centres (up to the widened ones)."""
    n = len(h.pose_ids)
    k = np.arange(n)
    return GroundTruth(
        np.column_stack([20 * np.cos(2 * np.pi * k / n), 20 * np.sin(2 * np.pi * k / n), k]),
        list(h.pose_ids), np.zeros((1, 2)), ["L1"], ["door"], ["L1"] * n,
    )  # fmt: skip


def an_envelope(h: Hypothesis, grow: float = 1.0) -> Envelope:
    """Each pose and observation of ``h`` widened by ``grow`` metres."""
    poses = h.poses.copy()
    poses[:, :2] += [-grow, grow]
    observed = np.array([h.landmark(a) for a in h.assignment]) + np.array([-grow, grow])
    return Envelope(list(h.pose_ids), poses, observed)


def all_texts(fig: Figure) -> list[str]:
    """Every text of the figure: its own, and each axes' (titles, labels, annotations)."""
    texts = [t.get_text() for t in fig.findobj(matplotlib.text.Text)]
    return [t for t in texts if t]


def overlap(a: Bbox, b: Bbox) -> float:
    """The area (pixels²) two boxes share."""
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(w, 0.0) * max(h, 0.0)


def legends_off_the_data(fig: Figure) -> None:
    """Assert that no legend covers the plotting area of an axes that draws data, nor an
    axes' title or axis labels."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend()]
    assert legends, "the figure has no legend"
    plots = [ax for ax in fig.axes if ax.get_visible() and (ax.lines or ax.patches)]
    for legend, ax in itertools.product(legends, plots):
        box = legend.get_window_extent(renderer)
        covered = overlap(box, ax.get_window_extent(renderer))
        assert covered < 1.0, f"a legend covers {covered:.0f} px² of {ax.get_title()!r}"
        for text in (ax.title, ax.xaxis.label, ax.yaxis.label):
            if text.get_text() and text.get_visible():
                covered = overlap(box, text.get_window_extent(renderer))
                assert covered < 1.0, f"a legend covers {text.get_text()!r} ({covered:.0f} px²)"


def png_dpi(data: bytes) -> float:
    """The resolution a PNG records (its pHYs chunk), in pixels per inch."""
    at = 8
    while at < len(data):
        (length,) = struct.unpack(">I", data[at : at + 4])
        kind = data[at + 4 : at + 8]
        if kind == b"pHYs":
            x_per_metre, y_per_metre, unit = struct.unpack(">IIB", data[at + 8 : at + 17])
            assert unit == 1 and x_per_metre == y_per_metre
            return x_per_metre * 0.0254
        at += 12 + length
    raise AssertionError("no pHYs chunk: the PNG does not say its size")


# --------------------------------------------------------------------------- the truth
def test_the_truth_crosses_pair_landmarks_by_association_not_by_name():
    h = make_hypothesis()  # L1, L2: seen by observations 0, 2 and 1, 3
    _, ax = plt.subplots()
    drawn = plot_hypothesis_on_axes(ax, h, far_truth(), legend=False)
    (crosses,) = drawn["truth_landmarks"]
    xy = sorted(zip(crosses.get_xdata(), crosses.get_ydata(), strict=True))
    assert xy == [(5.0, 5.0), (10.0, -5.0)]  # L13 and L15, in the boxes called L1 and L2
    assert ax.get_xlim()[0] > -30.0  # the unseen true L1 is neither drawn nor framed
    # a search's names, first sighting first, pair the same way
    swapped = renamed(h, {"L1": "L2", "L2": "L1"})
    (crosses,) = plot_hypothesis_on_axes(ax, swapped, far_truth())["truth_landmarks"]
    assert sorted(zip(crosses.get_xdata(), crosses.get_ydata(), strict=True)) == xy


def test_a_hypothesis_merging_two_true_landmarks_shows_both():
    h = make_hypothesis()
    h.assignment = ["L1", "L1", "L1", "L1"]  # wrong: sees L13 and L15 as one landmark
    _, ax = plt.subplots()
    (crosses,) = plot_hypothesis_on_axes(ax, h, far_truth())["truth_landmarks"]
    assert len(crosses.get_xdata()) == 2


def test_a_truth_without_assignment_pairs_by_name():
    t = far_truth()
    t.assignment = []
    t.landmark_ids = ["L1", "L2", "L9"]
    _, ax = plt.subplots()
    (crosses,) = plot_hypothesis_on_axes(ax, make_hypothesis(), t)["truth_landmarks"]
    assert sorted(crosses.get_xdata()) == [5.0, 10.0]


def test_a_long_run_ticks_only_the_drawn_poses_and_draws_the_true_path():
    n = 1000
    h = make_long_hypothesis(n)
    truth = circle_truth(h)
    _, ax = plt.subplots()
    drawn = plot_hypothesis_on_axes(ax, h, truth)
    boxes = len(drawn_poses(h.poses))
    assert len(drawn["pose_boxes"]) == boxes <= MAX_POSE_BOXES
    assert len(drawn["truth_poses"][0].get_xdata()) == boxes
    assert len(drawn["truth_headings"][0].get_segments()) == boxes
    assert len(drawn["truth_path"][0].get_xdata()) == n
    labels = drawn["pose_labels"]
    assert 2 <= len(labels) <= 12  # a few, far apart: the circle is 2π·20 m long
    assert all("," not in t.get_text() for t in labels)


def test_pose_labels_do_not_pile_up_and_a_closed_loop_shares_one():
    corners = [(0.0, 0.0), (0.1, 0.0), (5.0, 0.0), (5.0, 5.0), (0.0, 5.0), (0.0, 0.0)]
    poses = np.array([[[x - 0.5, x + 0.5], [y - 0.5, y + 0.5], [0.0, 0.1]] for x, y in corners])
    h = Hypothesis([], [1, 2, 3, 4, 5, 9], poses, [], [], np.empty((0, 2, 2)))
    _, ax = plt.subplots()
    labels = [t.get_text() for t in plot_hypothesis_on_axes(ax, h)["pose_labels"]]
    # pose 2, a step from pose 1, shares its label; pose 9 closes the loop on pose 1
    assert labels == ["1, 9", "3", "4", "5"]


# --------------------------------------------------------------------------- stray text
def test_a_drawn_hypothesis_has_no_text_saying_there_is_none():
    for solution in (Solution([make_hypothesis()]), Solution([make_hypothesis()] * 2)):
        fig = plot_solution(solution, make_truth())
        texts = all_texts(fig)
        assert not [t for t in texts if "no hypothesis" in t or "nothing to draw" in t]
        assert any("pose box" == t for t in texts)  # the texts were found


# --------------------------------------------------------------------------- the envelope
def test_an_incomplete_search_with_no_hypothesis_draws_its_envelope():
    h = make_hypothesis()
    solution = Solution([], complete=False, envelope=an_envelope(h))
    fig = plot_solution(solution, far_truth())
    (ax,) = [a for a in fig.axes if a.get_visible()]
    outlines = [p for p in ax.patches if p.get_linestyle() == "-"]
    assert len(outlines) == 3  # one per pose of the envelope
    assert all(p.get_edgecolor()[:3] == matplotlib.colors.to_rgb(ENVELOPE_COLOR) for p in outlines)
    dotted = [p for p in ax.patches if p.get_linestyle() == ":"]
    assert len(dotted) == 2  # the two distinct sighted-landmark boxes
    texts = all_texts(fig)
    assert "pose envelope (any correspondence)" in texts
    assert "sighted landmark envelope" in texts
    assert "envelope" in fig.get_suptitle() and "INCOMPLETE" in fig.get_suptitle()
    assert not [t for t in texts if "nothing to draw" in t]
    legends_off_the_data(fig)


def test_the_envelope_is_drawn_under_every_survivor_which_the_panels_frame():
    h = make_hypothesis()
    survivors = [h, renamed(h, {"L1": "L2", "L2": "L1"})]
    fig = plot_solution(Solution(survivors, envelope=an_envelope(h, 0.1)))
    for ax in (a for a in fig.axes if a.get_visible()):
        envelope = [p for p in ax.patches if p.get_zorder() == 1.5]
        assert len(envelope) == 3
        assert all(
            p.get_edgecolor()[:3] == matplotlib.colors.to_rgb(ENVELOPE_COLOR) for p in envelope
        )
    assert "pose envelope (any correspondence)" in all_texts(fig)
    # an envelope far wider than the hypotheses (a search cut short) runs past the frame
    fig = plot_solution(Solution(survivors, envelope=an_envelope(h, 100.0)))
    ax = fig.axes[0]
    assert ax.get_xlim()[1] < h.poses[2, 0, 1] + 100.0  # the survivors stay readable
    assert "pose envelope (any correspondence,\nsome past the frame)" in all_texts(fig)


def test_the_envelope_alone_on_axes():
    _, ax = plt.subplots()
    drawn = plot_envelope_on_axes(ax, an_envelope(make_hypothesis()), far_truth(), legend=True)
    assert len(drawn["envelope_poses"]) == 3 and len(drawn["envelope_landmarks"]) == 2
    assert len(drawn["truth_landmarks"][0].get_xdata()) == 2  # those the observations see
    unbounded = an_envelope(make_hypothesis())
    unbounded.observations[0] = [[-np.inf, np.inf], [-np.inf, np.inf]]  # maybe an outlier
    drawn = plot_envelope_on_axes(ax, unbounded, landmarks=True)
    assert len(drawn["envelope_landmarks"]) == 2  # left out (observation 2 sees L1 too)


# --------------------------------------------------------------------------- legends
def test_legends_stay_off_the_data():
    h = make_hypothesis()
    legends_off_the_data(plot_solution(Solution([h], envelope=an_envelope(h)), make_truth()))
    legends_off_the_data(plot_solution(Solution([h] * 3), make_truth()))
    legends_off_the_data(plot_solution(Solution([make_long_hypothesis(400)])))


def test_the_evaluation_figure_keeps_legends_off_its_curves():
    h = make_long_hypothesis(300)
    truth = circle_truth(h)
    solution = Solution([h])
    fig = plot_evaluation(solution, truth, evaluate(solution, truth))
    legends_off_the_data(fig)
    left = fig.axes[0]
    assert len([p for p in left.patches if p.get_zorder() == 3]) <= MAX_POSE_BOXES


# --------------------------------------------------------------------------- resolution
@pytest.mark.parametrize("survivors", [1, 2])
def test_pngs_are_written_at_print_resolution(tmp_path, survivors):
    h = make_hypothesis()
    fig = plot_solution(Solution([h] * survivors, statistics={"candidates": 4}))
    width_inches = fig.get_size_inches()[0]
    path = tmp_path / "f.png"
    save_figure(fig, path)
    data = path.read_bytes()
    assert png_dpi(data) == pytest.approx(DPI, abs=0.01) and DPI >= 150
    (pixels,) = struct.unpack(">I", data[16:20])
    assert pixels >= 150 * 0.8 * width_inches  # cropped to its content, not shrunk
    assert zlib.crc32(data) != 0


# --------------------------------------------------------------------------- the paper's figure
def paper_like() -> tuple[Solution, Solution, GroundTruth, list[int]]:
    """A known solve and two survivors without ids that disagree on observation 2."""
    h = make_hypothesis()
    h.status = PROVEN
    known = Solution([h], consistency="lp")
    other = copy.deepcopy(h)
    other.assignment = ["L1", "L2", "L3", "L2"]
    other.landmark_ids = ["L1", "L2", "L3"]
    other.landmark_classes = ["door", "tree", "door"]
    other.landmarks = np.concatenate([h.landmarks, [[[3.0, 5.0], [3.0, 5.0]]]])
    unknown = Solution(
        [h, other],
        statistics={"candidates": 9},
        correspondence={"certain": [True, True, False, True]},
        envelope=an_envelope(h),
    )
    return known, unknown, make_truth(), [0, 1, 2, 2]


def test_the_paper_figure_shows_each_survivor_beside_the_known_solve(tmp_path):
    known, unknown, truth, poses = paper_like()
    fig = plot_known_and_unknown(known, unknown, truth, observation_poses=poses)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 3
    titles = [ax.get_title() for ax in axes]
    assert titles[0].startswith("landmark ids known")
    assert titles[1].startswith("without ids: survivor 1 of 2")
    assert "obs→L: 1 2 [1] 2" in titles[1] and "obs→L: 1 2 [3] 2" in titles[2]
    assert "2 hypotheses survived" in fig.get_suptitle()
    assert len({(ax.get_xlim(), ax.get_ylim()) for ax in axes}) == 1  # shared limits
    # the sightings: every observation's, the one the survivors disagree on in red
    for ax in axes[1:]:
        plain, red = (c for c in ax.collections if c.get_linewidth()[0] in (0.6, 1.4))
        assert len(plain.get_segments()) == 3 and len(red.get_segments()) == 1
    texts = all_texts(fig)
    assert not [t for t in texts if "no hypothesis" in t or "nothing to draw" in t]
    assert "sighting the survivors assign differently" in texts
    legends_off_the_data(fig)
    path = tmp_path / "paper.png"
    save_figure(fig, path, tight=False)
    assert png_dpi(path.read_bytes()) >= 150


def test_the_paper_figure_of_a_search_with_no_survivor_shows_its_envelope():
    known, unknown, truth, poses = paper_like()
    unknown.hypotheses, unknown.complete = [], False
    fig = plot_known_and_unknown(known, unknown, truth, observation_poses=poses)
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert len(axes) == 2
    assert axes[1].get_title().startswith("the envelope")
    assert "pose envelope (any correspondence)" in all_texts(fig)
    assert len(plot_known_and_unknown(known, None, truth).axes) == 1


def test_many_survivors_take_two_rows_beside_the_known_solve():
    known, unknown, truth, _ = paper_like()
    unknown.hypotheses = unknown.hypotheses * 3
    fig = plot_known_and_unknown(known, unknown, truth, max_hypotheses=5)
    lefts = sorted({round(ax.get_position().x0, 3) for ax in fig.axes})
    bottoms = sorted({round(ax.get_position().y0, 3) for ax in fig.axes})
    assert len(fig.axes) == 6 and len(lefts) == 4 and len(bottoms) == 2
    assert "+1 more not shown" in fig.get_suptitle()
    legends_off_the_data(fig)
    with pytest.raises(ValueError, match="max_hypotheses"):
        plot_known_and_unknown(known, unknown, truth, max_hypotheses=0)


def test_cuikslam_plot_draws_the_envelope_of_a_result_with_no_hypothesis(tmp_path, capsys):
    from cuikslam.cli.main import main
    from cuikslam.results.io import write_result_file
    from cuikslam.simulate.truth import write_truth_file

    result, truth, figure = tmp_path / "r.json", tmp_path / "t.json", tmp_path / "r.png"
    write_result_file(Solution([], complete=False, envelope=an_envelope(make_hypothesis())), result)
    write_truth_file(far_truth(), truth)
    assert main(["plot", str(result), "--truth", str(truth), "-o", str(figure)]) == 0
    assert png_dpi(figure.read_bytes()) == pytest.approx(DPI, abs=0.01)
    write_result_file(Solution([], complete=True), result)  # refuted: nothing to draw
    assert main(["plot", str(result), "-o", str(tmp_path / "none.png")]) == 2
    assert "no hypothesis to plot (the log was refuted)" in capsys.readouterr().err
    assert not (tmp_path / "none.png").exists()
