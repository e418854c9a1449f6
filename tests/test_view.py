"""``cuikslam view``: the interactive page, its columns, its command, and the page in a real
browser (headless Chromium: no JavaScript error on the console, a screenshot that is not
blank, and the rendered DOM holds the content, before and after the selector and the
slider are moved)."""

from __future__ import annotations

import html
import json
import math
import re
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cuikslam.cli.main import main
from cuikslam.results.figures import MAX_POSE_BOXES, drawn_poses
from cuikslam.results.figures.geometry import _true_landmark_rows
from cuikslam.results.figures.page_data import hypothesis_layers, pose_order
from cuikslam.results.io import write_result_file
from cuikslam.results.solution import Hypothesis, Solution
from cuikslam.simulate.paper import simulate_paper
from cuikslam.simulate.truth import GroundTruth, write_truth_file
from cuikslam.solver import solve

pytest.importorskip("bokeh", reason='the page needs Bokeh: pip install "cuikslam[view]"')

from cuikslam.results.figures.page import build_page, write_page

LONG_POSES = 10_000
BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


# --------------------------------------------------------------------------- results
@pytest.fixture(scope="module")
def known():
    """The seed's experiment with its landmark ids (fast options: the page is tested)."""
    log, truth = simulate_paper(seed=0)
    return solve(log, consistency="hull", certify_limit=0, work_budget=None), truth


@pytest.fixture(scope="module")
def unknown():
    """The seed's experiment without ids: 2 survivors and an envelope."""
    log, truth = simulate_paper(seed=0, unknown=True)
    solution = solve(log, consistency="hull", certify_limit=0)
    assert len(solution.hypotheses) >= 2 and solution.envelope is not None
    return solution, truth


@pytest.fixture(scope="module")
def long_run():
    """The seed's octagon driven 1,250 laps (10,001 poses, known correspondence,
    ``benchmarks/long_log.py``), solved at level hull (about 2 s once the kernels are
    loaded; lp would take minutes)."""
    if str(BENCHMARKS) not in sys.path:
        sys.path.insert(0, str(BENCHMARKS))
    from long_log import octagon_log

    log, truth = octagon_log(LONG_POSES // 8)
    solution = solve(log, consistency="hull", certify_limit=0, work_budget=None)
    assert len(solution.best.pose_ids) == LONG_POSES + 1
    return solution, truth


@pytest.fixture(scope="module")
def long_synthetic():
    """A 10,000-pose known-correspondence result built synthetically, not solved, for
    what a solve of the octagon does not give (:func:`long_run`): a robot driving laps
    of a 12-sided loop, each pose box around the true pose, widening along the run, one
    pose with an unbounded side and one with any heading; four landmarks, each seen once
    per pose in turn. The truth lies in every box."""
    n = LONG_POSES
    rng = np.random.default_rng(0)
    step = np.arange(n)
    angle = 2 * math.pi * (step % 12) / 12
    xyt = np.column_stack((15 + 10 * np.cos(angle), 15 + 10 * np.sin(angle), angle + math.pi / 2))
    half = 0.2 + 1.5 * step / n + rng.uniform(0, 0.3, n)
    poses = np.stack((xyt - half[:, None] * [1, 1, 0.2], xyt + half[:, None] * [1, 1, 0.2]), 2)
    poses[n // 3, 1, 1] = math.inf
    poses[n // 2, 2] = (-math.inf, math.inf)
    marks_xy = np.array([[15.0, 30.0], [0.0, 15.0], [30.0, 15.0], [15.0, 0.0]])
    ids = ["door1", "door2", "corridor", "post"]
    assignment = [ids[i % 4] for i in range(n)]
    hypothesis = Hypothesis(
        assignment=assignment,
        pose_ids=list(range(1, n + 1)),
        poses=poses,
        landmark_ids=ids,
        landmark_classes=["door", "door", "corridor", "post"],
        landmarks=np.stack((marks_xy - 0.5, marks_xy + 0.5), axis=2),
        consistency="hull",
    )
    truth = GroundTruth(xyt, list(range(1, n + 1)), marks_xy, ids, hypothesis.landmark_classes,
                        assignment)  # fmt: skip
    return Solution([hypothesis], consistency="hull"), truth


@pytest.fixture(scope="module")
def envelope_alone(unknown):
    """A search stopped before its first hypothesis: the envelope alone (the seed's, with
    its hypotheses dropped)."""
    solution, truth = unknown
    return replace(solution, hypotheses=[], complete=False), truth


RESULTS = ["known", "unknown", "long_run"]
"""The results whose pages are loaded in the browser (and ``long_synthetic``, whose
boxes have an unbounded side and an unknown heading, and ``envelope_alone``, in the
render test)."""


# --------------------------------------------------------------------------- the columns
def test_long_run_draws_what_the_figures_draw(long_synthetic):
    solution, truth = long_synthetic
    h = solution.best
    order = {p: i for i, p in enumerate(pose_order(solution))}
    extent = (-10.0, 40.0, -10.0, 40.0)
    layers = hypothesis_layers(h, truth, extent, order, {}, MAX_POSE_BOXES)
    drawn = drawn_poses(h.poses)
    boxes = len(layers["pose_boxes"]["left"]) + len(layers["pose_boxes_unbounded"]["left"])
    assert boxes == len(drawn) <= MAX_POSE_BOXES
    assert len(layers["pose_boxes_unbounded"]["left"]) == 1  # pose n/3: the widest, drawn
    assert len(layers["path"]["x"]) == LONG_POSES  # the path runs through every pose
    assert len(layers["truth_poses"]["x"]) == len(drawn)  # dots on the drawn poses only
    assert len(layers["truth_path"]["x"]) == LONG_POSES
    ks = np.concatenate([layers["pose_boxes"]["k"], layers["pose_boxes_unbounded"]["k"]])
    assert sorted(ks) == list(drawn + 1)  # the slider's place of each: pose order, from 1


def test_truth_crosses_are_paired_by_association(unknown):
    solution, truth = unknown
    order = {p: i for i, p in enumerate(pose_order(solution))}
    for h in solution.hypotheses:
        layers = hypothesis_layers(h, truth, (-20, 50, -20, 50), order, {}, MAX_POSE_BOXES)
        rows = _true_landmark_rows(h, truth)
        assert layers["truth_landmarks"]["name"] == [f"true {truth.landmark_ids[j]}" for j in rows]
        assert rows  # through the association (the survivors name landmarks by sighting)


def test_page_is_self_contained_and_holds_the_summary(unknown):
    solution, truth = unknown
    page = build_page(solution, truth, title="a <title>")
    assert "<title>a &lt;title&gt;</title>" in page
    assert not re.search(r"<script[^>]+src=|<link[^>]+href=", page), "a resource is fetched"
    assert "cdn.bokeh.org" not in page
    assert "ambiguous (2 combinations: the 2 survivors)" in page
    assert "Hypothesis #2" in page  # every reported hypothesis' head is in the page


def test_a_refuted_result_has_nothing_to_view():
    with pytest.raises(ValueError, match="no hypothesis to view"):
        build_page(Solution([], complete=True))


def test_write_page_is_atomic(tmp_path, known, monkeypatch):
    import cuikslam.results.figures.page as page

    target = tmp_path / "page.html"
    target.write_text("old")

    def broken(*args, **kwargs):
        raise RuntimeError("boom")

    monkeypatch.setattr(page, "build_page", broken)
    with pytest.raises(RuntimeError):
        write_page(known[0], target)
    assert target.read_text() == "old" and list(tmp_path.iterdir()) == [target]


# --------------------------------------------------------------------------- the command
def _write(tmp_path: Path, result) -> tuple[Path, Path]:
    solution, truth = result
    result_path, truth_path = tmp_path / "r.result.json", tmp_path / "r.truth.json"
    write_result_file(solution, result_path)
    write_truth_file(truth, truth_path)
    return result_path, truth_path


def test_view_writes_the_page(tmp_path, unknown, capsys):
    result, truth = _write(tmp_path, unknown)
    page = tmp_path / "page.html"
    assert main(["view", str(result), "--truth", str(truth), "-o", str(page)]) == 0
    assert "wrote" in capsys.readouterr().err
    assert page.read_text(encoding="utf-8").startswith("<!DOCTYPE html>")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.html", *_names(result, truth)]


def _names(*paths: Path) -> list[str]:
    return sorted(p.name for p in paths)


@pytest.mark.parametrize(
    "content, expected",
    [
        ('{"hypotheses": [', "r.result.json:1: malformed JSON"),
        ("", "r.result.json"),
        ('{"complete": true, "hypotheses": [{"poses": 3}]}', "r.result.json"),
    ],
)
def test_a_bad_result_is_one_line_naming_the_file(tmp_path, capsys, content, expected):
    result = tmp_path / "r.result.json"
    result.write_text(content)
    page = tmp_path / "page.html"
    assert main(["view", str(result), "-o", str(page)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert expected in err, err
    assert list(tmp_path.iterdir()) == [result]  # no page, no temporary file


def test_a_page_name_must_end_with_html(tmp_path, capsys, known):
    result, _ = _write(tmp_path, known)
    assert main(["view", str(result), "-o", str(tmp_path / "page.png")]) == 2
    assert "page.png: a page's name ends with .html" in capsys.readouterr().err


def test_without_bokeh_the_command_says_what_to_install(tmp_path, capsys, known, monkeypatch):
    result, _ = _write(tmp_path, known)
    for name in [m for m in sys.modules if m == "bokeh" or m.startswith("bokeh.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "bokeh", None)  # import bokeh raises ImportError
    page = tmp_path / "page.html"
    assert main(["view", str(result), "-o", str(page)]) == 2
    err = capsys.readouterr().err
    hint = 'the page needs Bokeh, which is not installed: pip install "cuikslam[view]"'
    assert err == f"cuikslam: error: {hint}\n"
    assert not page.exists()


# --------------------------------------------------------------------------- in a browser
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
    "--enable-logging=stderr",
    "--v=0",
    "--virtual-time-budget=15000",  # let the page's scripts and the probe's timers run
]
CONSOLE = re.compile(r':CONSOLE[:(]\d+\)?\] "(.*)", source: ', re.M)
"""A console message as Chromium 156 logs it on stderr; every level (log, warn, error, an
uncaught exception) comes as INFO, so the probe tags errors and warnings itself."""
ERROR_TAG = "CUIKSLAM-CONSOLE-ERROR"

PROBE = """<script>
(function () {
  for (const level of ["error", "warn"]) {
    const original = console[level].bind(console);
    console[level] = (...args) => original("%TAG% " + level + ": " + args.map(String).join(" "));
  }
  window.addEventListener("unhandledrejection", (e) => console.error("unhandled: " + e.reason));
  function deepText(node) {
    const parts = [];
    const walk = (n) => {
      if (n.nodeName === "SCRIPT" || n.nodeName === "STYLE") return;
      if (n.nodeType === 3) parts.push(n.textContent);
      if (n.shadowRoot) walk(n.shadowRoot);
      for (const c of n.childNodes) walk(c);
    };
    walk(node);
    return parts.join(" ").replace(/\\s+/g, " ");
  }
  function count(node, name) {
    let n = node.nodeName === name ? 1 : 0;
    if (node.shadowRoot) n += count(node.shadowRoot, name);
    for (const c of node.childNodes) n += count(c, name);
    return n;
  }
  function sizes(doc) {
    const out = {};
    for (const m of doc.all_models) {
      if (m.name && m.name.startsWith("shown:")) {
        const columns = Object.values(m.data);
        out[m.name.slice(6)] = columns.length ? columns[0].length : 0;
      }
    }
    return out;
  }
  function report(out) {
    const pre = document.createElement("pre");
    pre.id = "cuikslam-probe";
    pre.textContent = JSON.stringify(out);
    document.body.appendChild(pre);
  }
  let tries = 0;
  function run() {
    const docs = window.Bokeh && window.Bokeh.documents;
    if (!docs || !docs.length || count(document.body, "CANVAS") === 0) {
      if (++tries < 200) { setTimeout(run, 50); } else { report({timeout: true}); }
      return;
    }
    const doc = docs[0];
    const out = {canvases: count(document.body, "CANVAS"), text: deepText(document.body),
                 sizes: sizes(doc)};
    const select = doc.get_model_by_name("hypothesis");
    const slider = doc.get_model_by_name("poses");
    if (select) select.value = String(select.options.length - 1);
    if (slider) slider.value = 3;
    setTimeout(() => {
      out.moved = {text: deepText(document.body), sizes: sizes(doc)};
      report(out);
    }, 500);
  }
  window.addEventListener("load", () => setTimeout(run, 50));
})();
</script>""".replace("%TAG%", ERROR_TAG)


def chromium() -> str:
    """The browser, or a skip that says how to get it."""
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found is None:
        pytest.skip(
            "chromium is not installed (apt-get install chromium; .ci/run installs it): "
            "the page is not checked in a browser"
        )
    return found


def run_chromium(page: Path, tmp_path: Path, *args: str) -> subprocess.CompletedProcess:
    profile = tmp_path / f"profile-{len(list(tmp_path.glob('profile-*')))}"
    command = [chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args, page.as_uri()]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180)
    assert done.returncode == 0, done.stderr[-3000:]
    return done


def console_errors(stderr: str) -> list[str]:
    """The console messages that are errors: tagged by the probe, uncaught exceptions, and
    resources that failed to load."""
    return [
        m
        for m in CONSOLE.findall(stderr)
        if m.startswith(ERROR_TAG) or m.startswith("Uncaught") or "Failed to load" in m
    ]


def probe(page_html: str, tmp_path: Path) -> tuple[dict, list[str]]:
    """Load the page with the probe, return what it found and the console's errors."""
    path = tmp_path / "probed.html"
    path.write_text(page_html.replace("<head>", "<head>" + PROBE, 1), encoding="utf-8")
    done = run_chromium(path, tmp_path, "--dump-dom")
    found = re.search(r'<pre id="cuikslam-probe">(.*?)</pre>', done.stdout, re.S)
    assert found, f"the probe reported nothing; console: {CONSOLE.findall(done.stderr)}"
    return json.loads(html.unescape(found.group(1))), console_errors(done.stderr)


def test_the_console_check_catches_an_error(tmp_path):
    """The check can fail: a page that logs an error and throws is caught twice."""
    page = "<html><head></head><body><canvas></canvas><script>window.Bokeh = {documents: []};"
    page += "console.error('deliberate'); throw new Error('on purpose');</script></body></html>"
    found, errors = probe(page, tmp_path)
    assert found == {"timeout": True}
    assert any("deliberate" in e for e in errors), errors
    assert any(e.startswith("Uncaught Error: on purpose") for e in errors), errors


EXPECTED = {
    "known": ["Known correspondence", "known correspondence · level hull", "true landmark"],
    "unknown": [
        "12 of 13 observations are associated for certain",
        "pose envelope",
        "Hypothesis #1",
        "#10 → #1 or new",
    ],
    "long_run": ["10,001 poses, ", "boxes drawn", "Known correspondence"],
    "long_synthetic": ["10,000 poses, ", "boxes drawn", "each of the 10,000 observations"],
    "envelope_alone": ["no hypothesis reported", "search INCOMPLETE", "sighted landmark envelope"],
}


@pytest.mark.parametrize("name", [*RESULTS, "long_synthetic", "envelope_alone"])
def test_the_page_renders_in_chromium(name, request, tmp_path):
    solution, truth = request.getfixturevalue(name)
    found, errors = probe(build_page(solution, truth), tmp_path)
    assert not errors, errors
    assert "timeout" not in found
    assert found["canvases"] >= 1
    if name.startswith("long"):  # the zoom on the widest stretch: every box of 30 poses
        zoomed = found["sizes"]["zoom_pose_boxes"] + found["sizes"].get(
            "zoom_pose_boxes_unbounded", 0
        )
        assert zoomed == 30 and found["canvases"] >= 2, found["sizes"]
    for words in EXPECTED[name]:
        assert words in found["text"], (words, found["text"][:3000])
    # the slider at 3: the path and the drawn boxes up to the third pose
    moved = found["moved"]
    boxes = "pose_boxes" if solution.hypotheses else "envelope_poses"
    assert 0 < moved["sizes"][boxes] <= 3 < found["sizes"][boxes], moved["sizes"]
    if solution.hypotheses:
        assert moved["sizes"]["path"] == 3, moved["sizes"]
    else:  # the envelope alone: where each sighted landmark lies, and the truth
        assert found["sizes"]["envelope_landmarks"] > 0 and found["sizes"]["truth_landmarks"]
    assert f"(3 of {len(pose_order(solution))})" in moved["text"]
    if len(solution.hypotheses) > 1:  # the selector shows the last hypothesis' head
        assert f"Hypothesis #{len(solution.hypotheses)}" in moved["text"]
        assert "Hypothesis #1 " not in moved["text"]


@pytest.mark.parametrize("name", RESULTS)
def test_the_screenshot_is_not_blank(name, request, tmp_path):
    from matplotlib.image import imread

    solution, truth = request.getfixturevalue(name)
    path = tmp_path / "page.html"
    write_page(solution, path, truth)
    shot = tmp_path / "page.png"
    done = run_chromium(path, tmp_path, f"--screenshot={shot}", "--window-size=1200,900")
    assert not console_errors(done.stderr)
    pixels = (imread(shot)[..., :3] * 255).round().astype(np.uint8)
    colours = len(np.unique(pixels.reshape(-1, 3), axis=0))
    inked = (pixels < 230).any(axis=2).mean()
    assert colours > 50, colours
    assert inked > 0.03, inked
