"""Random true worlds and their logs, for the guarantee tests; independent of the product.

Nothing here uses :mod:`cuikslam.simulate` (the simulator the product ships): the worlds,
their exact truth and the sensor rules are computed afresh, in the 1300-bit reference
context of :mod:`_exact`, so that a mistake shared by the simulator and the solver cannot
hide a broken guarantee.

A world is a random walk of poses (turn, then drive; with revisits of earlier places and
loop closures by odometry back to an earlier pose; pose ids in time order or not),
landmarks in classes (some clustered closer than the measurement error), priors on
some landmarks, an optional ``sensor`` record of any kind, and the observations that the
sensor rules of ``docs/log-format.md`` *require*: from every pose, every landmark in view.
Every measured interval is built around the exact true value with random non-negative
margins (zero included) and rounded outward, so the exact truth is always inside.
"""

from __future__ import annotations

import json
import math
import random
from collections.abc import Collection, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from decimal import Decimal
from pathlib import Path
from typing import Any

import mpmath
import numpy as np
import pytest
from hypothesis import assume
from hypothesis import strategies as st

from _exact import MP, TWO_PI, angle_inside, mpf
from cuikslam.hypotheses import explorer
from cuikslam.log import LandmarkPrior, Log, Observation, Odometry, PosePrior, parse_log_lines
from cuikslam.results.solution import Hypothesis, Solution

__all__ = [
    "EDGE",
    "SEARCHED",
    "SEARCH_LEVELS",
    "SENSOR_KINDS",
    "SMALL",
    "Truth",
    "World",
    "correspondence",
    "down",
    "log_violations",
    "partition",
    "search_level",
    "true_index",
    "truth_misses",
    "up",
    "worlds",
]

PI = MP.pi
EDGE = 1e-7
"""No landmark is generated closer than this to a visibility boundary (range, field of view,
nearest margin): on the boundary itself the rules are ambiguous."""
SMALL: dict[str, Any] = {"poses": (4, 8), "landmarks": (2, 5), "max_observations": 14}
"""Sizes of :func:`worlds` for the searches of the slow runs: small enough for most
searches to complete."""
SEARCHED: dict[str, Any] = {**SMALL, "max_observations": 10}
"""Sizes of :func:`worlds` for the searches of the default runs: up to 10 observations.
Nearly all of their searches complete, and as many complete with several survivors as
with :data:`SMALL` worlds, at a fifth of the cost (``test_guarantee.py``): the searches of
11 to 14 unlabelled observations are the ones that run into their node budgets."""
SEARCH_LEVELS: dict[str, dict[str, Any]] = {
    "hull": {"consistency": "hull"},
    "lp": {"consistency": "lp", "strengthen_limit": 10_000},
    "lp-during": {"consistency": "lp", "strengthen_limit": 0, "strengthen_during": 50},
}
"""Options of ``solve_unknown`` for each level: ``hull``; ``lp`` on every survivor after the
search; ``lp`` during the search (on every ambiguous node of the first 50 decisions, small
logs included: run it inside :func:`search_level`)."""


@contextmanager
def search_level(level: str) -> Iterator[None]:
    """Where a level of ``SEARCH_LEVELS`` needs it, the search's constants set for it:
    ``lp-during`` narrows every ambiguous node, however few the decisions (by default only
    logs of ``explorer.AMBIGUITY_LP_MIN_DECISIONS`` do, every ``AMBIGUITY_LP_GAP``)."""
    if level != "lp-during":
        yield
        return
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(explorer, "AMBIGUITY_LP_MIN_DECISIONS", 0)
        patch.setattr(explorer, "AMBIGUITY_LP_GAP", 1)
        yield


SENSOR_KINDS = ("none", "R", "F", "M", "RF", "RM", "FM", "RFM")
"""Sensor records: R = ``max_range``, F = ``fov``, M = ``nearest_margin``, and mixes."""


# --- outward rounding -------------------------------------------------------------------


def down(v: mpmath.mpf) -> float:
    """The largest float <= ``v``."""
    f = float(v)
    return float(np.nextafter(f, -math.inf)) if mpf(f) > v else f


def up(v: mpmath.mpf) -> float:
    """The smallest float >= ``v``."""
    f = float(v)
    return float(np.nextafter(f, math.inf)) if mpf(f) < v else f


def wrap(angle: mpmath.mpf) -> mpmath.mpf:
    """``angle`` wrapped to [-π, π)."""
    return angle - TWO_PI * MP.floor((angle + PI) / TWO_PI)


# --- the truth --------------------------------------------------------------------------


Offset = tuple[mpmath.mpf, mpmath.mpf, mpmath.mpf]


@dataclass
class Truth:
    """A true world: poses ``id -> (x, y, θ)``, landmarks ``id -> (x, y)`` (reference reals)."""

    poses: dict[int, tuple[mpmath.mpf, mpmath.mpf, mpmath.mpf]]
    landmarks: dict[str, tuple[mpmath.mpf, mpmath.mpf]]
    classes: dict[str, str]
    assignment: list[str]
    """The true landmark of each observation, in record order."""
    resolution: mpmath.mpf = field(default_factory=lambda: MP.mpf(2) ** -1200)
    """Relative accuracy of the values (derived poses are irrational): only
    :func:`log_violations` uses it, to check the test data, never a solver's box."""
    offsets: list[Offset | None] = field(default_factory=list)
    """The true sensor offset of each observation (record order), when it has one."""

    @classmethod
    def from_file(cls, path: Path) -> Truth:
        """Read a truth file of the reproducers' layout (decimal strings)."""
        doc = json.loads(Path(path).read_text(encoding="utf-8"))
        poses = {int(k): tuple(MP.mpf(str(v)) for v in xyt) for k, xyt in doc["poses"].items()}
        landmarks = {k: (MP.mpf(str(v[0])), MP.mpf(str(v[1]))) for k, v in doc["landmarks"].items()}
        classes = {k: v[2] for k, v in doc["landmarks"].items()}
        assignment = doc.get("obs_truth", doc.get("observation_landmark"))
        # up to 60 significant digits: derived values are that accurate, no more
        return cls(poses, landmarks, classes, list(assignment), MP.mpf("1e-55"))  # type: ignore[arg-type]

    def to_json(self) -> dict[str, Any]:
        """The reproducers' truth layout: decimal strings, exact for floats, else 60 digits."""
        return {
            "poses": {str(p): [_decimal(v) for v in xyt] for p, xyt in self.poses.items()},
            "landmarks": {
                lid: [_decimal(x), _decimal(y), self.classes[lid]]
                for lid, (x, y) in self.landmarks.items()
            },
            "obs_truth": list(self.assignment),
        }

    def range_bearing(
        self, pose: int, landmark: str, offset: Offset | None = None
    ) -> tuple[mpmath.mpf, mpmath.mpf]:
        """The true distance and bearing (wrapped to [-π, π)) of ``landmark`` from ``pose``,
        or from its sensor at ``offset`` ``(dx, dy, dθ)`` in the frame of the pose."""
        x, y, theta = self.poses[pose]
        if offset is not None:
            dx, dy, dt = offset
            c, s = MP.cos(theta), MP.sin(theta)
            x, y, theta = x + dx * c - dy * s, y + dx * s + dy * c, theta + dt
        lx, ly = self.landmarks[landmark]
        return MP.hypot(lx - x, ly - y), wrap(MP.atan2(ly - y, lx - x) - theta)


def _decimal(v: mpmath.mpf) -> str:
    f = float(v)
    if mpf(f) == v:
        return str(Decimal(f))  # exact: a float has a finite decimal expansion
    return MP.nstr(v, 60, min_fixed=-math.inf, max_fixed=math.inf)


# --- sensor rules -----------------------------------------------------------------------


@dataclass(frozen=True)
class Sensor:
    """A ``sensor`` record; ``None`` fields are left out."""

    max_range: float | None = None
    fov: float | None = None
    nearest_margin: float | None = None

    def record(self) -> dict[str, Any]:
        fields = {
            "max_range": self.max_range,
            "fov": self.fov,
            "nearest_margin": self.nearest_margin,
        }
        return {"type": "sensor", **{k: v for k, v in fields.items() if v is not None}}

    def in_view(self, truth: Truth, pose: int) -> tuple[set[str], mpmath.mpf]:
        """The landmarks the robot must observe from ``pose``, and how far the nearest
        landmark is from a boundary of these rules (compare with :data:`EDGE`)."""
        gap = MP.inf
        view: dict[str, mpmath.mpf] = {}
        for lid in truth.landmarks:
            distance, bearing = truth.range_bearing(pose, lid)
            inside = True
            if self.max_range is not None:
                gap = min(gap, abs(distance - mpf(self.max_range)))
                inside = distance < mpf(self.max_range)
            if self.fov is not None and self.fov < 2 * math.pi:  # the reader's clamp: fl(2π)
                half = mpf(self.fov) / 2
                gap = min(gap, abs(abs(bearing) - half))
                inside = inside and abs(bearing) < half
            if inside:
                view[lid] = distance
        if self.nearest_margin is not None and view:
            limit = min(view.values()) + mpf(self.nearest_margin)
            gap = min([gap, *(abs(d - limit) for d in view.values())])
            view = {lid: d for lid, d in view.items() if d <= limit}
        return set(view), gap


def sensor_of(log: Log) -> Sensor | None:
    """The log's sensor record as a :class:`Sensor` (``None`` without one)."""
    s = log.sensor
    if s is None:
        return None
    return Sensor(
        max_range=None if math.isinf(s.max_range) else s.max_range,
        fov=None if s.fov >= 2 * math.pi else s.fov,
        nearest_margin=s.nearest_margin,
    )


def log_violations(log: Log, truth: Truth) -> list[str]:
    """Every record of ``log`` whose intervals miss ``truth`` (exactly, angles mod 2π), and
    every pose that did not observe a landmark the sensor rules say it saw.

    An empty list means the log is a valid measurement of the world, so every guarantee of
    the solver applies to it.
    """
    bad: list[str] = []

    def slack(v: mpmath.mpf) -> mpmath.mpf:
        return truth.resolution * (abs(v) + 1)

    def within(lo: float, hi: float, v: mpmath.mpf) -> bool:
        return mpf(lo) - slack(v) <= v <= mpf(hi) + slack(v)

    def angle_within(lo: float, hi: float, v: mpmath.mpf) -> bool:
        low = mpf(lo) - slack(v) - TWO_PI * slack(v)
        k = MP.ceil((low - v) / TWO_PI)
        return v + k * TWO_PI <= mpf(hi) + slack(v) * (1 + abs(k))

    observations = 0
    seen: dict[object, set[str]] = {}
    for r in log.records:
        if isinstance(r, PosePrior):
            x, y, t = truth.poses[r.pose]
            if not (within(*r.x, x) and within(*r.y, y) and angle_within(*r.theta, t)):
                bad.append(f"line {r.line}: prior misses pose {r.pose}")
        elif isinstance(r, Odometry):
            x0, y0, t0 = truth.poses[r.source]
            x1, y1, t1 = truth.poses[r.target]
            d = MP.hypot(x1 - x0, y1 - y0)
            drift = abs(x1 - x0 - d * MP.cos(t1)) + abs(y1 - y0 - d * MP.sin(t1))
            if not (within(*r.distance, d) and angle_within(*r.turn, t1 - t0)):
                bad.append(f"line {r.line}: odometry misses the move {r.source} -> {r.target}")
            if drift > slack(d) * 100:
                bad.append(f"line {r.line}: the true move is not turn-then-drive ({drift})")
        elif isinstance(r, Observation):
            lid = truth.assignment[observations]
            offset = truth.offsets[observations] if truth.offsets else None
            observations += 1
            if (offset is None) != (r.offset is None):
                bad.append(f"line {r.line}: offset {r.offset}, truly {offset}")
            elif offset is not None and not all(
                within(*bounds, v) for bounds, v in zip(r.offset, offset, strict=True)
            ):
                bad.append(f"line {r.line}: the offset misses the sensor's")
            scan = r.pose if r.offset is None else (r.pose, r.offset)
            seen.setdefault(scan, set())
            if lid in seen[scan]:
                bad.append(f"line {r.line}: scan {scan} sees {lid} twice")
            seen[scan].add(lid)
            d, b = truth.range_bearing(r.pose, lid, offset)
            if r.landmark is not None and r.landmark != lid:
                bad.append(f"line {r.line}: named {r.landmark}, truly {lid}")
            if r.landmark_class != truth.classes[lid]:
                bad.append(f"line {r.line}: class {r.landmark_class} for {lid}")
            if r.range is not None and not within(*r.range, d):
                bad.append(f"line {r.line}: range misses {lid}")
            if r.bearing is not None and not angle_within(*r.bearing, b):
                bad.append(f"line {r.line}: bearing misses {lid}")
        elif isinstance(r, LandmarkPrior):
            x, y = truth.landmarks[r.landmark]
            if not (within(*r.x, x) and within(*r.y, y)):
                bad.append(f"line {r.line}: landmark prior misses {r.landmark}")
            if r.landmark_class != truth.classes[r.landmark]:
                bad.append(f"line {r.line}: class of {r.landmark}")
    if observations != len(truth.assignment):
        bad.append(f"{observations} observations, {len(truth.assignment)} true landmarks")
    sensor = sensor_of(log)
    if sensor is not None:
        for pose in log.pose_ids:
            view, _ = sensor.in_view(truth, pose)
            if missed := view - seen.get(pose, set()):
                bad.append(f"pose {pose} must have observed {sorted(missed)}")
    return bad


# --- checking a solution ----------------------------------------------------------------


def partition(assignment: Sequence[str]) -> tuple[int, ...]:
    """Landmark labels renumbered by first appearance: equal for equal partitions."""
    first: dict[str, int] = {}
    return tuple(first.setdefault(a, len(first)) for a in assignment)


def correspondence(assignment: Sequence[str], named: Collection[str]) -> tuple[object, ...]:
    """The partition, with each part that is a landmark the log names (``named``: landmark
    records and named observations) kept under its id: two hypotheses with the same
    partition that give a part to different named landmarks are different hypotheses."""
    first: dict[str, int] = {}
    return tuple(a if a in named else first.setdefault(a, len(first)) for a in assignment)


def true_index(solution: Solution, truth: Truth, named: Collection[str] = ()) -> int:
    """Index of the survivor with the true correspondence (see :func:`correspondence`), or -1."""
    target = correspondence(truth.assignment, named)
    for i, h in enumerate(solution.hypotheses):
        if correspondence(h.assignment, named) == target:
            return i
    return -1


def truth_misses(h: Hypothesis, truth: Truth, named: Collection[str] = ()) -> list[str]:
    """Every bound of ``h`` that misses the truth, compared exactly (headings mod 2π).

    ``h`` must have the true correspondence (:func:`true_index`). Its landmarks are matched
    to the true ones through the observations, and the landmarks the log names (``named``:
    ids of landmark records and named observations, which are the true ids) by id.
    """
    misses: list[str] = []
    for k, pose in enumerate(h.pose_ids):
        x, y, t = truth.poses[pose]
        box = h.poses[k]
        for name, v, (lo, hi) in (("x", x, box[0]), ("y", y, box[1])):
            if not mpf(lo) <= v <= mpf(hi):
                misses.append(f"pose {pose} {name}={MP.nstr(v, 20)} not in [{lo!r}, {hi!r}]")
        if not angle_inside(float(box[2, 0]), float(box[2, 1]), t):
            misses.append(f"pose {pose} theta={MP.nstr(t, 20)} not in {box[2].tolist()} mod 2π")
    names = dict(zip(h.assignment, truth.assignment, strict=True))
    names.update({lid: lid for lid in named if lid in h.landmark_ids})
    for ours, theirs in names.items():
        box = h.landmark(ours)
        for name, v, (lo, hi) in zip(("x", "y"), truth.landmarks[theirs], box, strict=True):
            if not mpf(lo) <= v <= mpf(hi):
                misses.append(
                    f"landmark {ours} (truly {theirs}) {name}={MP.nstr(v, 20)} "
                    f"not in [{lo!r}, {hi!r}]"
                )
    return misses


# --- worlds -----------------------------------------------------------------------------


@dataclass
class World:
    """A true world and the records of its log (observations carry their true landmark)."""

    truth: Truth
    records: list[dict[str, Any]]
    named: list[bool]
    """For a mixed log: whether each observation (record order) names its landmark."""
    sensor: Sensor | None
    notes: list[str] = field(default_factory=list)

    def __repr__(self) -> str:  # Hypothesis prints this in a falsifying example
        return f"World({self.notes[0]}; {len(self.records)} records; see the notes for the log)"

    def lines(self, naming: str = "mixed") -> list[str]:
        """The log's JSON lines; ``naming`` is ``all``, ``none`` or ``mixed`` (``named``)."""
        out, k = [], 0
        for record in self.records:
            record = dict(record)
            if record["type"] == "observation":
                keep = {"all": True, "none": False, "mixed": self.named[k]}[naming]
                k += 1
                if not keep:
                    del record["landmark"]
            out.append(json.dumps(record))
        return out

    def log(self, naming: str = "mixed") -> Log:
        return parse_log_lines(self.lines(naming))

    def named_ids(self, naming: str = "mixed") -> set[str]:
        """Landmark ids the log names (landmark records and named observations)."""
        log = self.log(naming)
        return {r.landmark for r in log.landmark_priors} | {
            o.landmark for o in log.observations if o.landmark is not None
        }

    def save(self, folder: Path, stem: str, naming: str = "mixed") -> Path:
        """Write ``stem.jsonl`` and ``stem.truth.json`` in ``folder``; the log's path."""
        folder.mkdir(parents=True, exist_ok=True)
        log_path = folder / f"{stem}.jsonl"
        log_path.write_text("\n".join(self.lines(naming)) + "\n", encoding="utf-8")
        (folder / f"{stem}.truth.json").write_text(json.dumps(self.truth.to_json()) + "\n")
        return log_path

    @property
    def n_observations(self) -> int:
        return len(self.truth.assignment)

    def with_class_priors(self, share: float, margin: float, extra: int) -> World:
        """This world with a ``class`` record per landmark class that its truth satisfies:
        ``at_most`` the true count plus ``extra``; ``min_separation`` ``share`` (in (0, 1])
        of the closest true pair of the class, rounded down; the region the landmarks' hull
        grown by ``margin``, rounded outward. Computed on the reference reals."""
        records = []
        for cls in sorted(set(self.truth.classes.values())):
            ids = [lid for lid, c in self.truth.classes.items() if c == cls]
            xs = [self.truth.landmarks[lid][0] for lid in ids]
            ys = [self.truth.landmarks[lid][1] for lid in ids]
            record: dict[str, Any] = {
                "type": "class",
                "class": cls,
                "at_most": len(ids) + extra,
                "x": [down(min(xs) - margin), up(max(xs) + margin)],
                "y": [down(min(ys) - margin), up(max(ys) + margin)],
            }
            gaps = [
                MP.hypot(xs[i] - xs[j], ys[i] - ys[j]) for i in range(len(ids)) for j in range(i)
            ]
            closest = min(gaps, default=None)
            if closest is not None and closest > 0 and down(closest * mpf(share)) > 0:
                record["min_separation"] = down(closest * mpf(share))
            records.append(record)
        notes = [*self.notes, f"class priors: {records}"]
        return replace(self, records=[*records, *self.records], notes=notes)


def _real(v: float) -> float:
    """A drawn coordinate, turn or distance, with magnitudes below 1e-100 made 0.

    Hypothesis' numbers include 1e-300 and the like; a product of two such with a sum of
    order 1 (``1 + d·sin θ``) would need more than the 1300 bits of the reference context.
    Tiny and huge magnitudes have their own tests (``test_odd_numbers.py``).
    """
    return 0.0 if abs(v) < 1e-100 else v


def _interval(
    rng: random.Random, v: mpmath.mpf, error: float, *, non_negative: bool = False
) -> list[float]:
    """A measured interval around the exact ``v``: each side a random margin in
    [0, error] (zero one time in six), rounded outward."""

    def margin() -> mpmath.mpf:
        return mpf(0.0) if rng.random() < 1 / 6 else mpf(rng.uniform(0.0, error))

    lo, hi = down(v - margin()), up(v + margin())
    return [max(lo, 0.0) if non_negative else lo, hi]


def _angle_interval(rng: random.Random, v: mpmath.mpf, error: float) -> list[float]:
    """An angle interval around ``v + 2πk``: k = 0 mostly, sometimes ±1 or 2."""
    k = rng.choice([0, 0, 0, 0, 0, 1, -1, 2])
    return _interval(rng, v + k * TWO_PI, error)


@st.composite
def worlds(
    draw: st.DrawFn,
    *,
    poses: tuple[int, int] = (4, 12),
    landmarks: tuple[int, int] = (2, 6),
    sensors: Sequence[str] = SENSOR_KINDS,
    max_observations: int = 60,
    named_fractions: Sequence[float] = (0.0, 0.25, 0.5, 0.8, 1.0),
    offsets: bool = False,
    scan_probability: float = 0.5,
    max_range: tuple[float, float] = (1.5, 7.0),
    true_random: bool | None = None,
) -> World:
    """A random true world and its log (see the module docstring).

    With ``offsets`` (and no sensor record, which cannot be combined with them), every
    observation is made from one of one or two sensors mounted off the robot's centre:
    a pose then has one scan per sensor, and two scans may see the same landmark.

    Structure (sizes, sensor kind, error bounds) is drawn directly; the many numbers of a
    world come from a Hypothesis-driven ``random.Random``, so they shrink too.

    Long worlds (see :data:`LONG`) need three more knobs: ``scan_probability``, the chance
    that a pose without a sensor record observes a landmark near it (the sensor rules
    decide for the others); ``max_range``, the range of a drawn ``max_range``; and
    ``true_random=True``, numbers from a true ``random.Random`` seeded by Hypothesis (a
    world of hundreds of poses draws more numbers than Hypothesis' buffer holds; then the
    shuffled pose ids come from it too). None draws the kind of numbers, as for small
    worlds.
    """
    # Hypothesis-made numbers find edge cases (zeros, equal values, exact 2π); true random
    # numbers (seeded by Hypothesis, so reproducible) find the generic ones.
    use_true_random = draw(st.booleans()) if true_random is None else true_random
    rng = draw(st.randoms(use_true_random=use_true_random))
    n_poses = draw(st.integers(*poses))
    n_landmarks = draw(st.integers(*landmarks))
    n_classes = draw(st.integers(1, 3))
    kind = draw(st.sampled_from(list(sensors)))
    mounts: list[Offset] = []
    if offsets:
        assert kind == "none", "sensor offsets cannot be combined with a sensor record"
        for _ in range(draw(st.integers(1, 2))):
            dx = _real(rng.choice([0.219, rng.uniform(-0.5, 0.5)]))
            dy = _real(rng.choice([0.0, rng.uniform(-0.3, 0.3)]))
            dt = _real(rng.choice([0.0, 0.0, rng.uniform(-3.2, 3.2)]))
            mounts.append((mpf(dx), mpf(dy), mpf(dt)))
    errors = draw(
        st.fixed_dictionaries(
            {
                "turn": st.sampled_from([0.0, 0.002, 0.02, 0.1, 0.3]),
                "distance": st.sampled_from([0.0, 0.01, 0.05, 0.2]),
                "range": st.sampled_from([0.0, 0.01, 0.05, 0.2]),
                "bearing": st.sampled_from([0.0, 0.002, 0.02, 0.1]),
                "prior": st.sampled_from([0.0, 0.05, 0.5, 3.0]),
            }
        )
    )
    p_named = draw(st.sampled_from(list(named_fractions)))
    ids = draw(st.sampled_from(["consecutive", "consecutive", "stride", "shuffled"]))
    if ids == "shuffled" and true_random:  # a long world: Hypothesis' buffer is too small
        pose_ids = rng.sample(range(4 * n_poses), n_poses)
    elif ids == "shuffled":  # ids need not grow with time
        pose_ids = draw(st.permutations(range(4 * n_poses)))[:n_poses]
    else:
        pose_ids = [(3 if ids == "stride" else 1) * k for k in range(n_poses)]
    notes = [
        f"{n_poses} poses, {n_landmarks} landmarks, sensor {kind}, errors {errors}, pose ids {ids}"
    ]

    # landmarks: some clustered closer than the range error, in 1-3 classes
    landmark_xy: dict[str, tuple[float, float]] = {}
    classes: dict[str, str] = {}
    cluster = max(errors["range"], 0.01)
    for j in range(n_landmarks):
        if j and rng.random() < 0.3:
            bx, by = landmark_xy[f"L{rng.randrange(j)}"]
            xy = (bx + rng.uniform(-cluster, cluster), by + rng.uniform(-cluster, cluster))
        else:
            xy = (rng.uniform(-5.0, 5.0), rng.uniform(-5.0, 5.0))
        xy = (_real(xy[0]), _real(xy[1]))
        landmark_xy[f"L{j}"] = xy
        classes[f"L{j}"] = f"c{rng.randrange(n_classes)}"

    # poses: turn then drive, a random walk with revisits; exact in the reference context
    x0, y0 = _real(rng.uniform(-4.0, 4.0)), _real(rng.uniform(-4.0, 4.0))
    theta0 = _real(rng.choice([rng.uniform(-math.pi, math.pi), 0.0, rng.uniform(-9.0, 9.0)]))
    true_poses = {pose_ids[0]: (mpf(x0), mpf(y0), mpf(theta0))}
    moves: list[tuple[mpmath.mpf, mpmath.mpf]] = []  # exact (turn, distance) of each step
    closures: dict[int, tuple[int, mpmath.mpf]] = {}  # step k: odometry k -> q, distance d
    for k in range(1, n_poses):
        px, py, pt = true_poses[pose_ids[k - 1]]
        x, y, theta = float(px), float(py), float(pt)
        if k >= 3 and rng.random() < 0.15:
            # a loop closure by odometry: pose k lies d behind an earlier pose q, on q's
            # heading, so that "turn to θ_q, drive d" from k reaches q exactly
            q = pose_ids[rng.randrange(k - 2)]
            qx, qy, qt = true_poses[q]
            d = mpf(rng.uniform(0.3, 2.0))
            kx, ky = qx - d * MP.cos(qt), qy - d * MP.sin(qt)
            distance = MP.hypot(kx - px, ky - py)
            assume(distance > EDGE)
            t = MP.atan2(ky - py, kx - px)
            t += TWO_PI * MP.nint((pt - t) / TWO_PI)  # the heading copy nearest the last one
            moves.append((t - pt, distance))
            true_poses[pose_ids[k]] = (kx, ky, t)
            closures[k] = (q, d)
            continue
        if k >= 3 and rng.random() < 0.25:  # head back to an earlier place (a revisit)
            tx, ty, _ = (float(v) for v in true_poses[pose_ids[rng.randrange(k - 2)]])
            turn = math.atan2(ty - y, tx - x) - theta + rng.uniform(-0.05, 0.05)
            distance = math.hypot(tx - x, ty - y)
        elif math.hypot(x, y) > 6.0:  # wandered off: back towards the middle
            turn, distance = math.atan2(-y, -x) - theta, rng.uniform(0.5, 2.0)
        else:
            turn = rng.choice([rng.uniform(-math.pi, math.pi), 0.0, rng.uniform(-7.0, 7.0)])
            distance = rng.choice([rng.uniform(0.0, 2.0), 0.0, rng.uniform(0.0, 0.5)])
        turn, distance = _real(turn), _real(distance)
        moves.append((mpf(turn), mpf(distance)))
        t = pt + mpf(turn)
        true_poses[pose_ids[k]] = (
            px + mpf(distance) * MP.cos(t),
            py + mpf(distance) * MP.sin(t),
            t,
        )

    sensor = None
    if kind != "none":
        sensor = Sensor(
            max_range=rng.uniform(*max_range) if "R" in kind else None,
            fov=rng.choice([rng.uniform(0.5, 6.2), math.pi, 2 * math.pi, 7.0])
            if "F" in kind
            else None,
            nearest_margin=rng.uniform(0.05, 3.0) if "M" in kind else None,
        )
    truth = Truth(
        true_poses,
        {lid: (mpf(x), mpf(y)) for lid, (x, y) in landmark_xy.items()},
        classes,
        [],
    )

    # what each pose observes: with a sensor, exactly what its rules require
    scans: dict[int, list[tuple[str, int | None]]] = {}
    for pose in pose_ids:
        if sensor is not None:
            view, gap = sensor.in_view(truth, pose)
            assume(gap > EDGE)
            scan = [(lid, None) for lid in sorted(view)]
        elif mounts:  # one scan per sensor, made from where the sensor is
            scan = [
                (lid, m)
                for m, mount in enumerate(mounts)
                for lid in truth.landmarks
                if truth.range_bearing(pose, lid, mount)[0] < 6 and rng.random() < scan_probability
            ]
        else:
            near = [lid for lid in truth.landmarks if truth.range_bearing(pose, lid)[0] < 6]
            scan = [(lid, None) for lid in near if rng.random() < scan_probability]
        rng.shuffle(scan)
        scans[pose] = scan
    assume(sum(map(len, scans.values())) <= max_observations)

    # the records, in time order
    records: list[dict[str, Any]] = []
    mount_records = [
        {
            f"offset_{axis}": _interval(rng, v, errors["distance"] if axis != "theta" else 0.01)
            for axis, v in zip(("x", "y", "theta"), mount, strict=True)
        }
        for mount in mounts
    ]
    x, y, t = true_poses[pose_ids[0]]
    records.append(
        {
            "type": "prior",
            "pose": pose_ids[0],
            "x": _interval(rng, x, errors["prior"]),
            "y": _interval(rng, y, errors["prior"]),
            "theta": _angle_interval(rng, t, min(errors["prior"], 0.3)),
        }
    )
    for k, pose in enumerate(pose_ids):
        if k:
            turn, distance = moves[k - 1]
            records.append(
                {
                    "type": "odometry",
                    "from": pose_ids[k - 1],
                    "to": pose,
                    "turn": _angle_interval(rng, turn, errors["turn"]),
                    "distance": _interval(rng, distance, errors["distance"], non_negative=True),
                }
            )
            if rng.random() < 0.08:  # an extra, loose prior (e.g. a GPS fix) on a reached pose
                other = pose_ids[rng.randrange(k + 1)]
                x, y, t = true_poses[other]
                records.append(
                    {
                        "type": "prior",
                        "pose": other,
                        "x": _interval(rng, x, 2.0),
                        "y": _interval(rng, y, 2.0),
                        "theta": _angle_interval(rng, t, 4.0),
                    }
                )
        for lid, m in scans[pose]:
            mount = None if m is None else mounts[m]
            d, b = truth.range_bearing(pose, lid, mount)
            which = rng.choice(["both", "both", "both", "both", "range", "bearing"])
            record: dict[str, Any] = {"type": "observation", "pose": pose, "class": classes[lid]}
            if mount is not None:  # the same intervals for every observation of the sensor
                record.update(mount_records[m])
                truth.offsets.append(mount)
            if which != "bearing":
                record["range"] = _interval(rng, d, errors["range"], non_negative=True)
            if which != "range":
                record["bearing"] = _angle_interval(rng, b, errors["bearing"])
            record["landmark"] = lid
            records.append(record)
            truth.assignment.append(lid)
        if k in closures:  # after the scan: back to the earlier pose q
            q, d = closures[k]
            back = true_poses[q][2] - true_poses[pose][2]
            records.append(
                {
                    "type": "odometry",
                    "from": pose,
                    "to": q,
                    "turn": _angle_interval(rng, back, errors["turn"]),
                    "distance": _interval(rng, d, errors["distance"], non_negative=True),
                }
            )
    # landmark priors (a partially known map), mostly first, some later in the log
    for lid, (lx, ly) in truth.landmarks.items():
        if rng.random() < 0.3:
            where = 1 if rng.random() < 0.7 else rng.randrange(1, len(records) + 1)
            records.insert(
                where,
                {
                    "type": "landmark",
                    "id": lid,
                    "class": classes[lid],
                    "x": _interval(rng, lx, max(errors["prior"], 0.1)),
                    "y": _interval(rng, ly, max(errors["prior"], 0.1)),
                },
            )
    if sensor is not None:
        records.insert(rng.randrange(len(records) + 1), sensor.record())
    named = [rng.random() < p_named for _ in truth.assignment]
    return World(truth, records, named, sensor, notes)
