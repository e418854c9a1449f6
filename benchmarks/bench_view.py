"""Benchmark: the page of ``cuikslam view`` for a 10,000-pose result: the time to build it,
its size, and the time headless Chromium takes to load and render it.

The result is the seed's octagon driven 1,250 laps (10,001 poses, known correspondence,
:mod:`long_log`), solved at level ``hull`` (about half a minute; ``--result`` and
``--truth`` take files instead). Then, in a fresh interpreter:

* **cold**: the first :func:`~cuikslam.results.figures.page.build_page` of the process,
  Bokeh's import included (what ``cuikslam view`` pays once per run);
* **warm**: the median of ``--repeat`` more builds in the same process;
* the result file's read time, apart.

Then the page's size in bytes and, when ``chromium`` is installed, the wall time of a
headless Chromium loading it (process start included; a tiny page's time given beside
it) and BokehJS's own "document idle" time from the console. The load average is printed
with the figures (the machine is shared). Results go to ``benchmarks/results/view.json``.

    python benchmarks/bench_view.py [--repeat 5] [--result R.json --truth T.json]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

_CHILD = r"""
import json, statistics, sys, time
result, truth, page, repeat = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4])
t = time.perf_counter()
from cuikslam import read_result_file, read_truth_file
solution, ground = read_result_file(result), read_truth_file(truth)
read_s = time.perf_counter() - t
t = time.perf_counter()
from cuikslam.results.figures.page import build_page
text = build_page(solution, ground)
cold_s = time.perf_counter() - t
warm = []
for _ in range(repeat):
    t = time.perf_counter()
    text = build_page(solution, ground)
    warm.append(time.perf_counter() - t)
with open(page, "w", encoding="utf-8") as f:
    f.write(text)
print(json.dumps({"read_s": read_s, "cold_s": cold_s, "warm_s": statistics.median(warm),
                  "warm_all_s": warm, "poses": len(solution.best.pose_ids)}))
"""

FLAGS = [
    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
    "--disable-background-networking", "--disable-component-update", "--disable-sync",
    "--enable-logging=stderr", "--v=0",
]  # fmt: skip


def _load() -> str:
    return "load {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())


def solved_result(folder: Path) -> tuple[Path, Path]:
    """The 10,000-pose octagon, solved at hull, written to ``folder``."""
    sys.path.insert(0, str(HERE))
    import cuikslam
    from cuikslam.simulate.truth import write_truth_file
    from long_log import octagon_log

    log, truth = octagon_log(1250)
    started = time.perf_counter()
    solution = cuikslam.solve(
        log, consistency="hull", certify_limit=0, work_budget=None, time_budget=None
    )
    print(f"solved {len(log.pose_ids):,} poses at hull in {time.perf_counter() - started:.1f} s")
    result, truth_path = folder / "long.result.json", folder / "long.truth.json"
    cuikslam.write_result_file(solution, result)
    write_truth_file(truth, truth_path)
    return result, truth_path


def chromium_times(page: Path, folder: Path) -> dict | None:
    """Wall seconds of headless Chromium screenshotting ``page`` and a tiny page; and
    BokehJS's "document idle" milliseconds."""
    browser = shutil.which("chromium")
    if browser is None:
        return None
    tiny = folder / "tiny.html"
    tiny.write_text("<html><body>tiny</body></html>")
    out: dict = {}
    for name, target in (("tiny_s", tiny), ("page_s", page)):
        started = time.perf_counter()
        done = subprocess.run(
            [browser, *FLAGS, f"--user-data-dir={folder / name}", "--window-size=1200,900",
             "--virtual-time-budget=15000", f"--screenshot={folder / (name + '.png')}",
             target.as_uri()],
            capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        out[name] = time.perf_counter() - started
        idle = re.search(r"document idle at (\d+) ms", done.stderr)
        if idle:
            out["bokeh_idle_ms"] = int(idle.group(1))
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5, help="warm builds (default 5)")
    parser.add_argument("--result", type=Path, help="a result file (default: solve the octagon)")
    parser.add_argument("--truth", type=Path, help="its truth file (with --result)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        if args.result is None:
            result, truth = solved_result(folder)
        else:
            result, truth = args.result, args.truth
        page = folder / "page.html"
        load_before = _load()
        done = subprocess.run(
            [sys.executable, "-c", _CHILD, str(result), str(truth), str(page), str(args.repeat)],
            capture_output=True, text=True, check=True,
        )  # fmt: skip
        figures = json.loads(done.stdout.strip().splitlines()[-1])
        figures["page_bytes"] = page.stat().st_size
        figures["chromium"] = chromium_times(page, folder)
        figures["load_before"], figures["load_after"] = load_before, _load()
    print(
        f"{figures['poses']:,} poses: read {figures['read_s']:.2f} s; build cold "
        f"{figures['cold_s']:.2f} s (Bokeh's import included), warm {figures['warm_s']:.2f} s "
        f"(median of {args.repeat}); page {figures['page_bytes']:,} bytes"
    )
    if figures["chromium"]:
        c = figures["chromium"]
        print(
            f"headless chromium: {c['page_s']:.2f} s for the page, {c['tiny_s']:.2f} s for a "
            f"tiny page; BokehJS document idle at {c.get('bokeh_idle_ms', '?')} ms"
        )
    print(f"{figures['load_before']} before, {figures['load_after']} after")
    out = HERE / "results" / "view.json"
    out.write_text(json.dumps(figures, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
