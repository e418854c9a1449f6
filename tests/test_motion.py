"""Composition of motion steps into keyframes encloses the exact true motion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from _exact import MP, mpf
from cuikslam.motion import compose_relative, compose_steps

speeds = st.floats(-1.0, 1.0)
rates = st.floats(-1.0, 1.0)


def _arc(x, y, t, v, w, dt):
    """Exact pose after driving at constant speed v and turn rate w for dt.

    The differences of sines and cosines are taken as products (sin a - sin b =
    2 cos((a+b)/2) sin((a-b)/2), cos a - cos b = -2 sin((a+b)/2) sin((a-b)/2)): written as
    differences they cancel to 0 at any fixed precision for angles near 1e-235, and the
    oracle then missed a true y of 3.5e-236 (a CI run's falsifying example)."""
    if w == 0:
        return x + v * dt * MP.cos(t), y + v * dt * MP.sin(t), t
    t2 = t + w * dt
    half, mid = (t2 - t) / 2, (t2 + t) / 2
    dsin = 2 * MP.cos(mid) * MP.sin(half)
    dcos = -2 * MP.sin(mid) * MP.sin(half)
    return x + v / w * dsin, y - v / w * dcos, t2


def _inside(bounds, value):
    return mpf(bounds[0]) <= value <= mpf(bounds[1])


@settings(max_examples=200, deadline=None)
@example(
    steps=[(1.0, 2.7982112213537127e-235, 0.0, 0.0, 0.125)],
    fractions=[0.0] * 8,
    drive=2.7982112213537127e-235,
    drive_error=0.0,
)
@given(
    steps=st.lists(
        st.tuples(speeds, rates, st.floats(0.0, 0.3), st.floats(0.0, 0.3), st.floats(0.01, 0.2)),
        min_size=1,
        max_size=15,
    ),
    fractions=st.lists(st.floats(0.0, 1.0), min_size=8, max_size=8),
    drive=st.floats(-0.2, 0.2),
    drive_error=st.floats(0.0, 0.05),
)
def test_true_motion_inside_the_composed_steps(steps, fractions, drive, drive_error):
    """The true speed and turn rate vary inside each step's intervals (piecewise constant on
    sub-steps); the exact final pose, in the frame of the first, is inside the result."""
    v, omega, times = [], [], [0.0]
    x, y, t = mpf(0), mpf(0), mpf(0)
    f = iter(fractions * 100)
    for speed, rate, dv, dw, dt in steps:
        v.append((speed - dv, speed + dv))
        omega.append((rate - dw, rate + dw))
        times.append(times[-1] + dt)
        duration = mpf(times[-1]) - mpf(times[-2])
        for _ in range(3):  # three sub-steps, each with its own true speed and turn rate
            true_v = mpf(speed - dv) + mpf(2 * dv) * mpf(next(f))
            true_w = mpf(rate - dw) + mpf(2 * dw) * mpf(next(f))
            # the robot drives along heading + drive angle; the arc is exact for that frame
            x, y, t = _arc(x, y, t + drive, true_v, true_w, duration / 3)
            t -= drive
    dx, dy, dtheta = compose_steps(
        v, omega, times, drive_angle=(drive - drive_error, drive + drive_error)
    )
    assert _inside(dx, x) and _inside(dy, y) and _inside(dtheta, t), (dx, dy, dtheta, x, y, t)


@settings(max_examples=200, deadline=None)
@given(
    moves=st.lists(
        st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-3, 3), st.floats(0, 0.1)),
        min_size=1,
        max_size=10,
    )
)
def test_composed_relative_poses_contain_the_truth(moves):
    x, y, t = mpf(0), mpf(0), mpf(0)
    boxes = []
    for dx, dy, dt, e in moves:
        x, y = x + MP.cos(t) * dx - MP.sin(t) * dy, y + MP.sin(t) * dx + MP.cos(t) * dy
        t = t + dt
        boxes.append(((dx - e, dx + e), (dy - e, dy + e), (dt - e, dt + e)))
    bx, by, bt = compose_relative(boxes)
    assert _inside(bx, x) and _inside(by, y) and _inside(bt, t)


def test_exact_steps_give_a_narrow_box_that_grows_with_the_errors():
    times = np.arange(11) * 0.1
    exact = compose_steps([(0.5, 0.5)] * 10, [(0.2, 0.2)] * 10, times)
    loose = compose_steps([(0.45, 0.55)] * 10, [(0.15, 0.25)] * 10, times)
    widths = [b[1] - b[0] for b in exact]
    assert exact[2][0] <= 0.2 <= exact[2][1] and widths[2] < 1e-12
    # a straight-line hull per step: about 0.5 m/s * 0.1 s * 0.02 rad = 1 mm per step
    assert max(widths[:2]) < 0.02
    assert all(l[1] - l[0] > w for l, w in zip(loose, widths, strict=True))


def test_bad_shapes_are_refused():
    with pytest.raises(ValueError, match="shape"):
        compose_steps([(0, 1)], [(0, 1), (0, 1)], [0.0, 0.1])
    with pytest.raises(ValueError, match="lo <= hi"):
        compose_steps([(1, 0)], [(0, 1)], [0.0, 0.1])
    with pytest.raises(ValueError, match="lo <= hi"):
        compose_relative([((0, 1), (1, 0), (0, 0))])
