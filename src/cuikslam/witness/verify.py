"""Rigorous verification: a parameter point proven, in interval arithmetic, to be a solution.

:func:`verify_witness` recomputes the poses with interval arithmetic from the parameter
point (degenerate intervals ``[v, v]``, every operation rounded outward) and checks that
every implied quantity lies *inside* its measured interval: plain inclusion for lengths and
coordinates, inclusion modulo 2 pi for angles (the shift ``2 pi k`` is itself an enclosure).
Bearings come from :func:`cuikslam.interval.angle_of` over a window wider than 2 pi, which
encloses every representative of the true angle in the window, hence at least one.

The frames are the robot poses and the sensor poses (a robot pose composed with an
observation's offset, whose parameters must lie in the offset's intervals like every other
parameter); ranges and bearings are measured from the sensor's frame. A loop-closing
``relative_pose`` record is three inequalities: the pose of its target in the frame of its
source, enclosed from the interval frames (:func:`._kinematics.relative_enclosure`), must lie
inside its ``dx`` and ``dy`` intervals and, modulo 2 pi, its ``dtheta`` interval; a point
strictly inside meets them with no equality to bracket.

Loop-closing odometry is an equality, which a single point cannot satisfy exactly in
floating point. It is verified with the Poincaré–Miranda theorem: one parameter per
closure (its *pivot*) is widened to a small interval; if every inequality check holds over
the whole parameter box and each closure's equality function has opposite strict signs on
the two faces of its pivot, the box contains a point where every equality holds exactly,
and that point satisfies every check. The returned witness is then the centre of that box
(within ``1e-3`` of an exact solution, in the parameters). An odometry from a pose to
itself needs no equality (it says turn ≡ 0 and distance = 0, both checked). Closures whose
equality vanishes identically otherwise (a duplicated odometry record) or whose
equalities are not independent cannot be verified this way: verification then fails,
which only leaves the hypothesis ``NOT_REFUTED``.

Only this module decides what counts as proven; everything else in the package merely
proposes points.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from cuikslam import interval as ia
from cuikslam.interval.angles import angles_inside, out_of_view_arc
from cuikslam.log.records import Log
from cuikslam.witness._kinematics import interval_kinematics, relative_enclosure
from cuikslam.witness.model import HypothesisModel, WitnessPoint

_WINDOW = 3.5
"""Half-width of the angle window given to ``angle_of``: more than pi, so the window holds
at least one representative of every angle."""
_PIVOT_STEPS = (1e-9, 1e-7, 1e-5, 1e-3)
"""Half-widths tried for the pivots of the Poincaré–Miranda box."""


def _inside(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """True where the interval ``x`` lies inside ``[lo, hi]`` (False for NaN or empty)."""
    return (x[..., 0] >= lo) & (x[..., 1] <= hi) & (x[..., 0] <= x[..., 1])


def _interval_world(model: HypothesisModel, box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Frames (n_frames, 3, 2: robot poses, then sensor poses) and landmarks (m, 2, 2)
    enclosing the world of every parameter in the parameter box ``box`` (n_params, 2), by
    outward-rounded forward kinematics."""
    P = interval_kinematics(model.n_frames, model.anchors, model.steps, box)
    L = box[model.landmark_param0 :].reshape(-1, 2, 2)
    return P, L


def _angle_enclosure(dy: np.ndarray, dx: np.ndarray) -> np.ndarray:
    """An enclosure of one representative of the angle of the vector (dx, dy).

    ``angle_of`` encloses every representative inside a window; the window is centred on
    the floating-point angle of the boxes' midpoints and is 7 wide, more than 2 pi, so it
    holds at least one representative, and only one unless the boxes are wide.
    """
    centre = np.arctan2(_mid(dy), _mid(dx))
    centre = np.where(np.isfinite(centre), centre, 0.0)
    window = ia.interval(centre - _WINDOW, centre + _WINDOW)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        return ia.angle_of(dy, dx, window)[2]


def _mid(x: np.ndarray) -> np.ndarray:
    with np.errstate(invalid="ignore", over="ignore"):
        return (x[..., 0] + x[..., 1]) / 2


def _checks_hold(model: HypothesisModel, box: np.ndarray) -> bool:
    """Every inequality check holds for every parameter in ``box`` (rigorous)."""
    if np.any(box[:, 0] < model.param_lo) or np.any(box[:, 1] > model.param_hi):
        return False
    if np.any(box[:, 0] > box[:, 1]):
        return False
    P, L = _interval_world(model, box)
    lo, hi = model.check_lo, model.check_hi
    pieces: list[np.ndarray] = []
    i, j = model.obs_pose, model.obs_landmark
    if len(i):
        dx = ia.sub(L[j, 0], P[i, 0])
        dy = ia.sub(L[j, 1], P[i, 1])
        rng = ia.sqrt(ia.add(ia.sqr(dx), ia.sqr(dy)))
        pieces.append(rng[model.range_sel])
        b = model.bearing_sel
        if len(b):
            phi = _angle_enclosure(dy[b], dx[b])
            pieces.append(ia.sub(phi, P[i[b], 2]))
    pieces.append(P[model.prior_pose, model.prior_coord].reshape(-1, 2))
    pieces.append(L[model.lprior_landmark, model.lprior_coord].reshape(-1, 2))
    s_, t_ = model.closure_source, model.closure_target
    if len(s_):
        same = (s_ == t_)[:, None]  # an odometry into its own pose: no turn, no move
        turn = np.where(same, 0.0, ia.sub(P[t_, 2], P[s_, 2]))
        ddx = np.where(same, 0.0, ia.sub(P[t_, 0], P[s_, 0]))
        ddy = np.where(same, 0.0, ia.sub(P[t_, 1], P[s_, 1]))
        dist = ia.add(ia.mul(ddx, ia.cos(P[t_, 2])), ia.mul(ddy, ia.sin(P[t_, 2])))
        pieces += [turn, dist]
    if len(model.loop_source):
        R = relative_enclosure(P, model.loop_source, model.loop_target)
        pieces += [R[:, 0], R[:, 1], R[:, 2]]
    values = np.concatenate([q.reshape(-1, 2) for q in pieces]) if pieces else np.zeros((0, 2))
    if values.shape[0] != model.n_checks:
        raise AssertionError("check layout mismatch")
    ang = model.check_angular
    ok_plain = _inside(values[~ang], lo[~ang], hi[~ang])
    ok_ang = angles_inside(values[ang], lo[ang], hi[ang])
    if not (np.all(ok_plain) and np.all(ok_ang)):
        return False
    return _sensor_holds(model, P[: model.n_poses], L) and _class_priors_hold(model, L)


def _class_priors_hold(model: HypothesisModel, L: np.ndarray) -> bool:
    """The log's class priors (rigorous): at most ``at_most`` landmarks of a class, each
    inside its region, any two at least ``min_separation`` apart."""
    classes = np.array(model.landmark_classes, dtype=object)
    for cls, prior in model.class_priors.items():
        mine = np.flatnonzero(classes == cls)
        if prior.at_most is not None and len(mine) > prior.at_most:
            return False
        if prior.x is not None and prior.y is not None and len(mine):
            box = L[mine]
            if np.any(box[:, 0, 0] < prior.x[0]) or np.any(box[:, 0, 1] > prior.x[1]):
                return False
            if np.any(box[:, 1, 0] < prior.y[0]) or np.any(box[:, 1, 1] > prior.y[1]):
                return False
        if prior.min_separation is not None and len(mine) > 1:
            a, b = np.triu_indices(len(mine), k=1)
            dx = ia.sub(L[mine[b], 0], L[mine[a], 0])
            dy = ia.sub(L[mine[b], 1], L[mine[a], 1])
            gap = ia.sqrt(ia.add(ia.sqr(dx), ia.sqr(dy)))
            if np.any(gap[:, 0] < prior.min_separation):
                return False
    return True


def _sensor_holds(model: HypothesisModel, P: np.ndarray, L: np.ndarray) -> bool:
    """Negative information (rigorous): at every pose the observed landmarks are exactly the
    ones the sensor is sure to see."""
    sensor = model.sensor
    n, m = model.n_poses, model.n_landmarks
    if sensor is None or n == 0 or m == 0:
        return True
    dx = ia.sub(L[None, :, 0], P[:, None, 0])
    dy = ia.sub(L[None, :, 1], P[:, None, 1])
    dist = ia.sqrt(ia.add(ia.sqr(dx), ia.sqr(dy)))
    in_range = dist[..., 1] <= sensor.max_range
    out_range = dist[..., 0] > sensor.max_range
    unseen = out_of_view_arc(sensor.fov, inner=True)  # a bearing in it is proven unseen
    if unseen is None:
        in_view = np.ones((n, m), dtype=bool)
        out_view = np.zeros((n, m), dtype=bool)
    else:
        half = sensor.fov / 2.0
        theta = np.broadcast_to(P[:, None, 2], (n, m, 2))
        bearing = ia.sub(_angle_enclosure(dy, dx), theta)
        in_view = angles_inside(bearing, -half, half)
        out_view = angles_inside(bearing, *unseen)
    visible = in_range & in_view
    hidden = out_range | out_view
    if not np.all(visible | hidden):
        return False
    observed = model.observed
    if sensor.nearest_margin is None:
        return bool(np.all(np.where(observed, visible, hidden)))
    margin = ia.interval(sensor.nearest_margin)
    for a in range(n):
        vis = visible[a]
        if not np.any(vis):
            if np.any(observed[a]):
                return False
            continue
        nearest = np.array([dist[a, vis, 0].min(), dist[a, vis, 1].min()])
        limit = ia.add(nearest, margin)
        seen = vis & (dist[a, :, 1] <= limit[0])
        unseen = hidden[a] | (dist[a, :, 0] > limit[1])
        if not np.all(np.where(observed[a], seen, unseen)):
            return False
    return True


def _equality_signs(model: HypothesisModel, box: np.ndarray) -> np.ndarray:
    """Enclosures (e, 2) of the closure equalities over a parameter box."""
    P, _ = _interval_world(model, box)
    s_ = model.closure_source[model.equality_rows]
    t_ = model.closure_target[model.equality_rows]
    ddx = ia.sub(P[t_, 0], P[s_, 0])
    ddy = ia.sub(P[t_, 1], P[s_, 1])
    return ia.sub(ia.mul(ddx, ia.sin(P[t_, 2])), ia.mul(ddy, ia.cos(P[t_, 2])))


def _pivots(model: HypothesisModel, p: np.ndarray) -> list[int] | None:
    """One distinct free parameter per closure equality, greedily the most sensitive."""
    _, J = model.equalities(p, jacobian=True)
    assert J is not None
    J = np.abs(J) * model.free[None, :]
    chosen: list[int] = []
    order = np.argsort(-J.max(axis=1)) if len(J) else []
    pivots = [0] * len(J)
    for c in order:
        row = J[c].copy()
        row[chosen] = 0.0
        k = int(np.argmax(row))
        if row[k] <= 0.0:
            return None
        chosen.append(k)
        pivots[c] = k
    return pivots


def verified_box(model: HypothesisModel, p: np.ndarray) -> np.ndarray | None:
    """A parameter box around ``p`` proven to contain a solution, or None."""
    if model.problems:
        return None
    p = np.asarray(p, dtype=float)
    if p.shape != (model.n_params,) or not np.all(np.isfinite(p)):
        return None
    box = np.stack([p, p], axis=-1)
    if len(model.equality_rows) == 0:
        return box if _checks_hold(model, box) else None
    pivots = _pivots(model, p)
    if pivots is None:
        return None
    for step in _PIVOT_STEPS:
        wide = box.copy()
        for k in pivots:
            wide[k] = (p[k] - step, p[k] + step)
        if not _checks_hold(model, wide):
            continue
        ok = True
        for c, k in enumerate(pivots):
            low = wide.copy()
            low[k] = (wide[k, 0], wide[k, 0])
            high = wide.copy()
            high[k] = (wide[k, 1], wide[k, 1])
            f_low = _equality_signs(model, low)[c]
            f_high = _equality_signs(model, high)[c]
            if not ((f_low[1] < 0.0 < f_high[0]) or (f_high[1] < 0.0 < f_low[0])):
                ok = False
                break
        if ok:
            return wide
    return None


def verify_witness(
    log: Log, assignment: Sequence[str], point: WitnessPoint | np.ndarray, use_sensor: bool = True
) -> bool:
    """Whether ``point`` (or a parameter vector) is proven to satisfy every check.

    Rigorous: the decision rests on outward-rounded interval arithmetic only. With
    loop-closing odometry, a True means that a small box around the point contains an
    exact solution (Poincaré–Miranda; see the module docstring).
    """
    model = HypothesisModel(log, assignment, use_sensor=use_sensor)
    params = point.params if isinstance(point, WitnessPoint) else point
    return verified_box(model, np.asarray(params, dtype=float)) is not None
