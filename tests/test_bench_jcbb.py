"""The GTSAM + JCBB baseline of ``benchmarks/bench_jcbb.py``: its association alone."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import pytest

pytest.importorskip(
    "gtsam", reason="the JCBB baseline needs gtsam (pip install 'cuikslam[interop]')"
)

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"
if str(BENCHMARKS) not in sys.path:
    sys.path.insert(0, str(BENCHMARKS))

from cuikslam.log.records import Log, Observation, Odometry, PosePrior  # noqa: E402
from jcbb import run_gtsam_jcbb  # noqa: E402


def _around(value: float, half: float) -> tuple[float, float]:
    return (value - half, value + half)


def _seen(pose: int, xy: tuple[float, float], point: tuple[float, float]) -> Observation:
    """A door at ``point`` seen from ``pose`` at ``xy`` heading 0, unlabelled."""
    dx, dy = point[0] - xy[0], point[1] - xy[1]
    return Observation(
        pose=pose,
        landmark_class="door",
        range=_around(math.hypot(dx, dy), 0.05),
        bearing=_around(math.atan2(dy, dx), 0.02),
    )


def test_jcbb_pairs_two_look_alike_doors_across_two_scans() -> None:
    a, b = (6.0, 0.0), (0.0, 6.0)  # two doors, 8.5 m apart
    log = Log(
        records=[
            PosePrior(pose=0, x=(0.0, 0.0), y=(0.0, 0.0), theta=(0.0, 0.0)),
            _seen(0, (0.0, 0.0), a),
            _seen(0, (0.0, 0.0), b),
            Odometry(source=0, target=1, turn=_around(0.0, 0.05), distance=_around(1.0, 0.1)),
            _seen(1, (1.0, 0.0), b),  # the second scan sees them in the other order
            _seen(1, (1.0, 0.0), a),
        ]
    )
    found = run_gtsam_jcbb(log).assignment
    assert found[0] != found[1]  # one scan: two distinct doors
    assert found[3] == found[0]  # a again
    assert found[2] == found[1]  # b again
    assert len(set(found)) == 2
