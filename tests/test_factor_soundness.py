"""The factor operators and the propagation never lose the truth.

A random world (a few poses driven by odometry or relative poses, a few landmarks) is
drawn with its exact truth: the free quantities are floats, and every derived one
(headings, positions, ranges, bearings) is computed in 1300-bit arithmetic. Every
measurement is an interval containing the true value with random bounded errors; angles
are given as unwrapped intervals (any copy ``+ 2πk``, sometimes wider than 2π). Then:

(a) after every single application of a factor's operator (``narrow_factor``), in random
    order, over many passes, every box contains the truth (angles modulo 2π) and is a
    subset of the box before;
(b) after the full fixpoint ``propagate(graph)`` the truth is inside and the status is
    CONSISTENT;
(c) the operators are monotone: narrowing a sub-box gives a sub-box of the narrowed box
    (angles modulo 2π);
(d) they are contracting: the result is a subset of the input.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from _exact import MP, TWO_PI, angle_inside, mpf
from cuikslam.graph.encoding import ANGLE, LENGTH
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.narrowing._factors import EMPTY_FACTOR, narrow_factor
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, DEFAULT_RTOL, Status, propagate

pytestmark = [
    pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning"),
    pytest.mark.filterwarnings("ignore:invalid value encountered:RuntimeWarning"),
]


PI = float(MP.pi)


def below(v: mpmath.mpf) -> float:
    """The largest float <= v."""
    f = float(v)
    return f if mpf(f) <= v else math.nextafter(f, -math.inf)


def above(v: mpmath.mpf) -> float:
    """The smallest float >= v."""
    f = float(v)
    return f if mpf(f) >= v else math.nextafter(f, math.inf)


# ---------------------------------------------------------------- random worlds


@dataclass
class World:
    graph: KinematicGraph
    truth: list[mpmath.mpf]
    """The true value of every variable (a real; for angles, one of its copies)."""
    is_angle: np.ndarray
    truth_below: np.ndarray
    truth_above: np.ndarray
    description: str

    def lost(self, lo: np.ndarray, hi: np.ndarray) -> list[str]:
        """The variables whose box no longer contains the truth (angles modulo 2π)."""
        bad = []
        plain = ~self.is_angle
        out = plain & ~((lo <= self.truth_below) & (self.truth_above <= hi))
        bad += [f"var {i}: [{lo[i]!r}, {hi[i]!r}] ∌ {self.truth[i]}" for i in np.flatnonzero(out)]
        for i in np.flatnonzero(self.is_angle):
            if not angle_inside(lo[i], hi[i], self.truth[i]):
                bad.append(f"angle var {i}: [{lo[i]!r}, {hi[i]!r}] ∌ {self.truth[i]} mod 2π")
        return bad


errors = st.one_of(
    st.just(0.0),
    st.sampled_from([1e-12, 1e-6, 1e-3, 0.05, 0.3]).flatmap(lambda e: st.floats(0.0, e)),
)
angle_errors = st.one_of(errors, st.floats(0.0, 1.0), st.sampled_from([3.0, 7.0]))


@st.composite
def worlds(draw, max_poses: int = 5, max_landmarks: int = 3) -> World:
    n_poses = draw(st.integers(2, max_poses))
    n_landmarks = draw(st.integers(1, max_landmarks))
    coord = st.floats(-20.0, 20.0)
    angle = st.one_of(st.floats(-PI, PI), st.sampled_from([0.0, PI, -PI, PI / 2, -PI / 2]))
    turns = st.one_of(angle, st.floats(-0.2, 0.2))
    dists = st.one_of(st.floats(0.0, 8.0), st.sampled_from([0.0, 1.0, 20.0]))
    wraps = st.one_of(st.just(0), st.integers(-2, 2), st.integers(-1000, 1000))

    def interval(v: mpmath.mpf, errs=errors, derived: bool = False) -> tuple[float, float]:
        lo, hi = below(v), above(v)
        if derived and lo == hi:  # a rounded transcendental value may look like a float
            lo, hi = math.nextafter(lo, -math.inf), math.nextafter(hi, math.inf)
        return lo - draw(errs), hi + draw(errs)

    def angle_interval(v: mpmath.mpf, derived: bool = False) -> tuple[float, float]:
        return interval(v + draw(wraps) * TWO_PI, angle_errors, derived=derived)

    graph = KinematicGraph()
    truth: dict[int, mpmath.mpf] = {}
    angles: set[int] = set()
    lines = []

    # poses: pose 0 has a prior (a point or a small box); the others follow the odometry
    x, y, t = mpf(draw(coord)), mpf(draw(coord)), mpf(draw(angle))
    point_prior = draw(st.booleans())
    err = st.just(0.0) if point_prior else errors
    graph.add_pose_prior(
        0,
        interval(x, err),
        interval(y, err),
        interval(t + draw(wraps) * TWO_PI, err),
    )
    poses = [(x, y, t)]
    for i in range(1, n_poses):
        if draw(st.booleans()):
            # a relative pose: (dx, dy) in the frame of pose i - 1, then the heading change
            dx, dy, dtheta = mpf(draw(coord)) / 4, mpf(draw(coord)) / 4, mpf(draw(turns))
            x = x + dx * MP.cos(t) - dy * MP.sin(t)
            y = y + dx * MP.sin(t) + dy * MP.cos(t)
            t = t + dtheta
            f = graph.add_relative_pose(
                i - 1, i, interval(dx), interval(dy), angle_interval(dtheta)
            )
            table = graph.factor_table()
            truth[int(table[f][ANGLE])], truth[int(table[f][LENGTH])] = dx, dy
            truth[int(table[f + 1][ANGLE])] = dtheta
            angles.add(int(table[f + 1][ANGLE]))
            poses.append((x, y, t))
            lines.append(
                f"relative pose {i - 1}->{i}: dx {float(dx):.6g}, dy {float(dy):.6g}, "
                f"dtheta {float(dtheta):.6g}"
            )
            continue
        turn, dist = mpf(draw(turns)), mpf(draw(dists))
        t = t + turn
        x, y = x + dist * MP.cos(t), y + dist * MP.sin(t)
        f = graph.add_odometry(i - 1, i, angle_interval(turn), interval(dist))
        row = graph.factor_table()[f]
        truth[int(row[ANGLE])], truth[int(row[LENGTH])] = turn, dist
        angles.add(int(row[ANGLE]))
        poses.append((x, y, t))
        lines.append(f"odometry {i - 1}->{i}: turn {float(turn):.6g}, dist {float(dist):.6g}")
    for i, (px, py, pt) in enumerate(poses):
        v = graph.pose_index(i)
        truth[v], truth[v + 1], truth[v + 2] = px, py, pt
        angles.add(v + 2)

    landmarks = []
    for j in range(n_landmarks):
        lx, ly = mpf(draw(coord)), mpf(draw(coord))
        landmarks.append((f"L{j}", lx, ly))
    n_obs = draw(st.integers(1, 2 * n_poses))
    for _ in range(n_obs):
        i = draw(st.integers(0, n_poses - 1))
        name, lx, ly = landmarks[draw(st.integers(0, n_landmarks - 1))]
        px, py, pt = poses[i]
        offset = None
        if draw(st.booleans()):
            # the sensor sits at (ox, oy), turned by ot, in the frame of the robot pose
            ox, oy, ot = mpf(draw(coord)) / 16, mpf(draw(coord)) / 16, mpf(draw(turns))
            offset = (interval(ox), interval(oy), angle_interval(ot))
            px = px + MP.cos(pt) * ox - MP.sin(pt) * oy
            py = py + MP.sin(pt) * ox + MP.cos(pt) * oy
            pt = pt + ot
        rng = MP.sqrt((lx - px) ** 2 + (ly - py) ** 2)
        if rng == 0:
            continue
        bearing = MP.atan2(ly - py, lx - px) - pt
        kind = draw(st.sampled_from(["range-bearing", "range-only", "bearing-only"]))
        f = graph.add_observation(
            i,
            name,
            range=None if kind == "bearing-only" else interval(rng, derived=True),
            bearing=None if kind == "range-only" else angle_interval(bearing, derived=True),
            offset=offset,
        )
        row = graph.factor_table()[f]
        truth[int(row[ANGLE])], truth[int(row[LENGTH])] = bearing, rng
        angles.add(int(row[ANGLE]))
        if offset is not None:
            o = int(row[1]) - 3  # the offset's variables, then the sensor's pose
            truth[o], truth[o + 1], truth[o + 2] = ox, oy, ot
            truth[o + 3], truth[o + 4], truth[o + 5] = px, py, pt
            angles.update((o + 2, o + 5))
            kind += " from an offset sensor"
        lines.append(f"{kind} {i}->{name}: range {float(rng):.6g}, bearing {float(bearing):.6g}")
    for name, lx, ly in landmarks:
        if name in graph.landmark_ids:
            v = graph.landmark_index(name)
            truth[v], truth[v + 1] = lx, ly
        else:  # a landmark nobody saw: not a variable
            continue

    n = graph.n_variables
    assert sorted(truth) == list(range(n))
    values = [truth[i] for i in range(n)]
    is_angle = np.zeros(n, dtype=bool)
    is_angle[list(angles)] = True
    world = World(
        graph=graph,
        truth=values,
        is_angle=is_angle,
        truth_below=np.array([below(v) for v in values]),
        truth_above=np.array([above(v) for v in values]),
        description="\n".join(lines),
    )
    lo, hi = graph.domains()
    assert world.lost(lo, hi) == [], "the generator's measurements must contain the truth"
    return world


settings_grid = st.sampled_from(
    [(DEFAULT_RTOL, DEFAULT_ROUNDS), (0.0, 20), (0.1, 1), (1e-6, 8), (0.0, 1)]
)


# ---------------------------------------------------------------- (a) and (d)


@settings(max_examples=300, deadline=None)
@given(world=worlds(), setting=settings_grid, seed=st.integers(0, 2**32 - 1))
def test_every_operator_application_keeps_the_truth(world, setting, seed):
    rtol, rounds = setting
    table = world.graph.factor_table()
    lo, hi = world.graph.domains()
    order = list(range(len(table)))
    rnd = random.Random(seed)
    for n_pass in range(6):
        rnd.shuffle(order)
        for f in order:
            before_lo, before_hi = lo.copy(), hi.copy()
            mask = narrow_factor(lo, hi, table[f], rtol, rounds)
            assert mask != EMPTY_FACTOR, (
                f"factor {f} proved a true world inconsistent (pass {n_pass})\n" + world.description
            )
            lost = world.lost(lo, hi)
            assert not lost, (f"factor {f}, pass {n_pass}", lost, world.description)
            # contractance, and the mask tells which slots shrank
            assert np.all(before_lo <= lo) and np.all(hi <= before_hi), f
            changed = (lo != before_lo) | (hi != before_hi)
            slots = {int(v) for v in table[f][1:] if v >= 0}
            assert set(np.flatnonzero(changed).tolist()) <= slots, f


# ---------------------------------------------------------------- (b)


@settings(max_examples=300, deadline=None)
@given(world=worlds(max_poses=6, max_landmarks=4), setting=settings_grid)
def test_fixpoint_keeps_the_truth_and_is_consistent(world, setting):
    rtol, rounds = setting
    result = propagate(world.graph, rtol=rtol, max_rounds=rounds)
    assert result.status is Status.CONSISTENT, world.description
    lost = world.lost(result.lo, result.hi)
    assert not lost, (lost, world.description)
    lo, hi = world.graph.domains()
    assert np.all(lo <= result.lo) and np.all(result.hi <= hi)
    # a second propagation from the fixpoint changes (almost) nothing and stays consistent
    again = propagate(world.graph, result.lo, result.hi, rtol=rtol, max_rounds=rounds)
    assert again.status is Status.CONSISTENT
    assert not world.lost(again.lo, again.hi)


# ---------------------------------------------------------------- (c) monotonicity


def _shrink(rnd: random.Random, lo: float, hi: float) -> tuple[float, float]:
    """A random sub-interval (of a finite, or a finite part of an infinite, interval)."""
    a = lo if math.isfinite(lo) else (hi if math.isfinite(hi) else 0.0) - rnd.uniform(0, 50)
    b = hi if math.isfinite(hi) else (lo if math.isfinite(lo) else 0.0) + rnd.uniform(0, 50)
    u, v = sorted((rnd.uniform(0, 1), rnd.uniform(0, 1)))
    new_lo, new_hi = a + u * (b - a), a + v * (b - a)
    return max(lo, min(new_lo, new_hi)), min(hi, max(new_lo, new_hi))


def _finite_angles(lo: np.ndarray, hi: np.ndarray, is_angle: np.ndarray) -> None:
    """Replace unbounded angle boxes by finite ones wider than 2π (still "any angle").

    An unbounded angle box is special: narrowing replaces it by one representative copy,
    e.g. tb in (-inf, inf) with ta = turn = 0 gives tb = [0, 0], whereas a finite sub-box
    [-24.5, -1.7] gives the hull of the copies there, [-6π, -2π]. So monotonicity holds
    for finite angle boxes, where the narrowed box is the hull of X ∩ (A + 2πZ).
    """
    for i in np.flatnonzero(is_angle):
        if not math.isfinite(lo[i]) or not math.isfinite(hi[i]):
            centre = lo[i] if math.isfinite(lo[i]) else hi[i] if math.isfinite(hi[i]) else 0.0
            lo[i], hi[i] = max(lo[i], centre - 40.0), min(hi[i], centre + 40.0)


@settings(max_examples=200, deadline=None)
@given(
    world=worlds(max_poses=4, max_landmarks=2),
    seed=st.integers(0, 2**32 - 1),
    rounds=st.sampled_from([1, 4, 20]),
    warm=st.booleans(),
)
def test_operators_are_monotone(world, seed, rounds, warm):
    """narrow(B') ⊆ narrow(B) for B' ⊆ B (rtol = 0: no early stop that depends on widths).

    Up to 1e-12 (relative) for the C library's sin, cos, atan2..., which are faithful, not
    necessarily monotone, in their last ulp.
    """
    rnd = random.Random(seed)
    table = world.graph.factor_table()
    lo, hi = world.graph.domains()
    if warm:
        result = propagate(world.graph, rtol=0.1, max_rounds=1)
        assert result.status is Status.CONSISTENT
        lo, hi = result.lo, result.hi
    _finite_angles(lo, hi, world.is_angle)
    for f in rnd.sample(range(len(table)), min(3, len(table))):
        row = table[f]
        slots = [int(v) for v in row[1:] if v >= 0]
        sub_lo, sub_hi = lo.copy(), hi.copy()
        for v in slots:
            if rnd.random() < 0.5:
                sub_lo[v], sub_hi[v] = _shrink(rnd, lo[v], hi[v])
        big_lo, big_hi = lo.copy(), hi.copy()
        small_lo, small_hi = sub_lo.copy(), sub_hi.copy()
        big = narrow_factor(big_lo, big_hi, row, 0.0, rounds)
        small = narrow_factor(small_lo, small_hi, row, 0.0, rounds)
        # contractance (d)
        assert np.all(sub_lo <= small_lo) and np.all(small_hi <= sub_hi)
        if small == EMPTY_FACTOR:
            continue
        assert big != EMPTY_FACTOR, ("the box is refuted but a sub-box is not", f, row)
        for v in slots:
            slack = 1e-12 * (1.0 + abs(big_lo[v]) + abs(big_hi[v]))
            slack = slack if math.isfinite(slack) else 0.0
            ok = big_lo[v] - slack <= small_lo[v] and small_hi[v] <= big_hi[v] + slack
            assert ok, (
                f"factor {f} (kind {row[0]}), var {v}: narrow(sub-box) = "
                f"[{small_lo[v]!r}, {small_hi[v]!r}] ⊄ narrow(box) = [{big_lo[v]!r}, {big_hi[v]!r}]"
                f"; sub-box [{sub_lo[v]!r}, {sub_hi[v]!r}], box [{lo[v]!r}, {hi[v]!r}]"
            )
