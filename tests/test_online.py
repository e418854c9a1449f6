"""The online session (:mod:`cuikslam.online`): its boxes hold the truth after every record,
it finishes poses when it should, and its growing arrays narrow like a batch graph.

The property tests use the guarantee tests' generator (:mod:`worlds`) and compare exactly
(headings modulo 2π), as ``test_guarantee.py`` does.
"""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from _exact import MP, angle_inside, mpf
from cuikslam.errors import InputFileError
from cuikslam.graph import KinematicGraph
from cuikslam.log import parse_log_lines
from cuikslam.log.records import (
    ClassPrior,
    LandmarkPrior,
    Observation,
    Odometry,
    PosePrior,
    RelativePose,
)
from cuikslam.narrowing.propagation import Status, propagate
from cuikslam.online import Session
from cuikslam.online.follow import FollowReport, Pacer, follow, log_lines
from cuikslam.online.growing import GrowingGraph
from cuikslam.results.association import partition
from cuikslam.simulate.paper import simulate_paper
from cuikslam.simulate.random_world import simulate_random_world
from cuikslam.solver import solve
from worlds import Truth, World, correspondence, log_violations, worlds

HEALTH = [HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large]
CI = settings(max_examples=80, deadline=None, derandomize=True, suppress_health_check=HEALTH)


def pose_misses(box: np.ndarray, truth: Truth, pose: int) -> list[str]:
    """The sides of a pose box (3, 2) that miss the true pose, exactly (heading mod 2π)."""
    x, y, t = truth.poses[pose]
    misses = [
        f"pose {pose} {name}={MP.nstr(v, 20)} not in [{lo!r}, {hi!r}]"
        for name, v, (lo, hi) in (("x", x, box[0]), ("y", y, box[1]))
        if not mpf(lo) <= v <= mpf(hi)
    ]
    if not angle_inside(float(box[2, 0]), float(box[2, 1]), t):
        misses.append(f"pose {pose} theta={MP.nstr(t, 20)} not in {box[2].tolist()} mod 2π")
    return misses


def landmark_misses(box: np.ndarray, truth: Truth, landmark: str) -> list[str]:
    return [
        f"landmark {landmark} {name}={MP.nstr(v, 20)} not in [{lo!r}, {hi!r}]"
        for name, v, (lo, hi) in zip(("x", "y"), truth.landmarks[landmark], box, strict=True)
        if not mpf(lo) <= v <= mpf(hi)
    ]


def named_world(world: World):
    """The world's log with every landmark named, and it measures the world."""
    note(world.notes[0])
    note("\n".join(world.lines("all")))
    log = world.log("all")
    assume(log_violations(log, world.truth) == [])
    return log


# --- the guarantee, online ---------------------------------------------------------------


@CI
@given(world=worlds())
def test_every_box_holds_the_truth_after_every_record(world: World) -> None:
    """Asked after each record, every pose and landmark box so far holds the truth."""
    log = named_world(world)
    session = Session()
    landmarks: set[str] = set()
    poses: set[int] = set()
    for record in log.records:
        session.add(record)
        match record:
            case Observation(landmark=landmark) | LandmarkPrior(landmark=landmark):
                landmarks.add(landmark)
            case PosePrior(pose=pose) | Odometry(target=pose):
                poses.add(pose)
        assert session.refuted is None, session.refuted
        for pose in poses:
            assert pose_misses(session.pose_box(pose), world.truth, pose) == []
        for landmark in landmarks:
            assert landmark_misses(session.landmark_box(landmark), world.truth, landmark) == []


@pytest.mark.parametrize("level", ["hull", "lp"])
@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds())
def test_every_finished_pose_holds_the_truth(world: World, level: str) -> None:
    """Each pose's box, given when the pose is finished (at ``lp``, after the windows of
    the poses before it), holds the truth; every pose reached is finished once, in the
    order the log first reaches it."""
    log = named_world(world)
    session = Session(consistency=level)
    estimates = []
    for record in log.records:
        estimate = session.add(record)
        if estimate is not None:
            estimates.append(estimate)
            session.settle()
    estimates.append(session.finish())
    assert session.refuted is None
    for pose in log.pose_ids:
        assert pose_misses(session.pose_box(pose), world.truth, pose) == []
    assert [e.pose for e in estimates] == list(log.pose_order())
    for estimate in estimates:
        assert estimate.hypotheses == 1
        assert pose_misses(estimate.box, world.truth, estimate.pose) == []


@CI
@given(world=worlds(sensors=("none",), offsets=True))
def test_offset_sensors_keep_the_truth_online(world: World) -> None:
    """Observations from sensors mounted off the robot's centre (a sensor pose per scan)."""
    log = named_world(world)
    session = Session()
    for record in log.records:
        session.add(record)
    last = session.finish()
    assert last is not None and session.refuted is None
    for pose in log.pose_ids:
        assert pose_misses(session.pose_box(pose), world.truth, pose) == []


TINY = {"poses": (3, 6), "landmarks": (2, 4), "max_observations": 10}
"""Worlds whose correspondence search is small enough to run again at every pose."""
SMALL = {"poses": (4, 8), "landmarks": (2, 5), "max_observations": 14}
"""The guarantee tests' worlds for searches (the slow run)."""


def check_unknown(world: World, naming: str) -> None:
    """Each finished pose's box (the hull over the live hypotheses), when it is given and
    asked again after every record, holds the truth, and the true correspondence is alive
    at the end."""
    note(world.notes[0])
    note("\n".join(world.lines(naming)))
    log = world.log(naming)
    assume(log_violations(log, world.truth) == [])
    session = Session()
    estimates = []
    for record in log.records:
        estimate = session.add(record)
        if estimate is not None:
            estimates.append(estimate)
        assert session.refuted is None, session.refuted
        for pose in session.finished:  # asked after every record
            assert pose_misses(session.pose_box(pose), world.truth, pose) == []
    estimates.append(session.finish())
    assert session.refuted is None, session.refuted
    for estimate in estimates:
        assert pose_misses(estimate.box, world.truth, estimate.pose) == []
    named = world.named_ids(naming)
    alive = {correspondence(a, named) for a in session.assignments()}
    assert correspondence(world.truth.assignment, named) in alive
    assert estimates[-1].hypotheses == len(session.assignments())


@pytest.mark.parametrize("naming", ["none", "mixed"])
@settings(max_examples=30, deadline=None, derandomize=True, suppress_health_check=HEALTH)
@given(world=worlds(**TINY))
def test_unknown_correspondence_keeps_the_truth_at_every_pose(world: World, naming: str) -> None:
    check_unknown(world, naming)


@pytest.mark.slow
@settings(max_examples=300, deadline=None, suppress_health_check=HEALTH)
@given(world=worlds(**SMALL), naming=st.sampled_from(["none", "mixed"]))
def test_slow_unknown_correspondence_online(world: World, naming: str) -> None:
    check_unknown(world, naming)


def test_the_seeds_experiment_online_keeps_the_batch_survivors() -> None:
    """Ids dropped: the last pose's live hypotheses are the batch solve's survivors."""
    log, truth = simulate_paper(seed=0, unknown=True)
    session = Session()
    counts = [e.hypotheses for e in map(session.add, log.records) if e is not None]
    last = session.finish()
    batch = solve(log, consistency="hull", certify_limit=0)
    online = sorted(partition(a, set()) for a in session.assignments())
    assert online == sorted(partition(h.assignment, set()) for h in batch.hypotheses)
    assert last.hypotheses == batch.statistics["survivors"] == 2 and max(counts) <= 2
    assert correspondence(truth.assignment, ()) in {correspondence(a, ()) for a in online}


def test_poses_reached_before_the_first_reading_without_an_id_keep_their_boxes() -> None:
    """Until the next pose is finished, the live hypotheses have no boxes of their own:
    a pose's box is then that of the records before the reading."""
    session = Session()
    session.add(PosePrior(0, (0, 0), (0, 0), (0, 0)))
    assert session.add(Odometry(0, 1, (0, 0), (1, 1.5))).pose == 0
    before = session.pose_box(1)
    session.add(Observation(1, "post", (1, 2), (-0.1, 0.1)))  # no id
    assert session.pose_box(0).tolist() == [[0, 0], [0, 0], [0, 0]]
    assert session.pose_box(1).tolist() == before.tolist()
    assert session.hypotheses == 1
    assert session.add(Odometry(1, 2, (0, 0), (1, 1))).pose == 1  # the first update
    assert session.pose_box(1)[0] == pytest.approx([1, 1.5]) and session.hypotheses == 1
    with pytest.raises(KeyError):
        session.pose_box(2)  # reached after the update


# --- when poses are finished ---------------------------------------------------------------


def test_a_pose_is_finished_when_a_record_reaches_a_later_one() -> None:
    session = Session()
    assert session.add(PosePrior(5, (0, 0), (0, 0), (0, 0), line=1)) is None
    assert session.add(Observation(5, "door", (1, 2), (0, 0.1), "A", line=2)) is None
    first = session.add(Odometry(5, 7, (0, 0.1), (1, 1.2), line=3))
    assert first is not None and first.pose == 5
    assert session.add(Observation(5, "door", (1, 2), (0, 0.1), "B", line=4)) is None
    closure = RelativePose(7, 5, (-1.5, -0.5), (-0.5, 0.5), (-0.5, 0.5), line=5)
    assert session.add(closure) is None  # back to a pose reached before
    second = session.add(RelativePose(7, 2, (1, 1), (0, 0), (0, 0), line=6))
    assert second is not None and second.pose == 7
    assert session.add(PosePrior(2, (-9, 9), (-9, 9), (-4, 4), line=7)) is None  # reached
    third = session.add(PosePrior(11, (0, 1), (0, 1), (0, 1), line=8))  # a new pose
    assert third is not None and third.pose == 2
    last = session.finish()
    assert last is not None and last.pose == 11
    assert session.finish() is None
    assert session.finished == [5, 7, 2, 11]


def test_records_after_a_pose_is_finished_still_narrow_it() -> None:
    """A landmark prior that comes late narrows the poses that saw the landmark."""
    session = Session()
    session.add(PosePrior(0, (-10, 10), (-10, 10), (0, 0)))
    session.add(Observation(0, "door", (1, 1), (0, 0), "A"))
    before = session.add(Odometry(0, 1, (0, 0), (1, 1)))
    session.add(LandmarkPrior("A", "door", (3, 3), (0, 0)))
    after = session.pose_box(0)
    assert before.box[0].tolist() == [-10, 10]
    assert after[0, 0] == pytest.approx(2.0) and after[0, 1] == pytest.approx(2.0)


def test_a_class_region_bounds_landmarks_named_before_and_after_it() -> None:
    session = Session()
    session.add(PosePrior(0, (0, 0), (0, 0), (0, 0)))
    session.add(Observation(0, "post", None, (0, 0.1), "early"))
    session.add(ClassPrior("post", x=(-1, 4), y=(-1, 4)))
    session.add(Observation(0, "post", None, (1.0, 1.1), "late"))
    early, late = session.landmark_box("early"), session.landmark_box("late")
    assert early[0, 1] == 4.0 and early[0, 0] >= -1.0
    assert late[1, 1] == 4.0 and late[0, 0] >= -1.0


def test_records_breaking_the_log_rules_are_refused_naming_their_line() -> None:
    session = Session(path="trip.jsonl")
    session.add(PosePrior(0, (0, 0), (0, 0), (0, 0), line=1))
    with pytest.raises(InputFileError, match=r"trip.jsonl:2: odometry from pose 3"):
        session.add(Odometry(3, 4, (0, 0), (1, 1), line=2))


def test_an_inconsistent_log_is_refuted_and_says_where() -> None:
    session = Session(path="trip.jsonl")
    session.add(PosePrior(0, (0, 0), (0, 0), (0, 0), line=1))
    session.add(Odometry(0, 1, (0, 0), (1, 1), line=2))
    assert session.add(PosePrior(1, (5, 6), (0, 0), (0, 0), line=3)) is None
    assert session.finish() is None
    assert session.refuted is not None and "lines 2-3" in session.refuted
    assert session.hypotheses == 0
    with pytest.raises(ValueError, match="inconsistent"):
        session.pose_box(0)


def test_the_lp_level_narrows_the_boxes_given_next() -> None:
    """On the seed's experiment (known correspondence) the windows' polytope hull makes
    the boxes of the later poses narrower than the fixpoint alone, and none wider."""
    log, _ = simulate_paper(seed=0)
    widths = {}
    for level in ("hull", "lp"):
        session = Session(consistency=level)
        boxes = []
        for record in log.records:
            estimate = session.add(record)
            if estimate is not None:
                boxes.append(estimate.box)
                session.settle()
        boxes.append(session.finish().box)
        widths[level] = np.diff(np.array(boxes)).squeeze(-1)
    assert np.all(widths["lp"] <= widths["hull"])
    assert np.all(widths["lp"][-1] < 0.8 * widths["hull"][-1])


def test_settle_keeps_the_window_from_a_time_it_could_overrun(monkeypatch) -> None:
    """On a clock that stands still, ``settle`` runs the hull narrowing while more than
    ``SETTLE_MARGIN_S`` is left, but not the ``lp`` window with less than twice
    ``WINDOW_MARGIN_S``: the boxes are then those of level hull; without ``until`` the
    window runs and narrows them."""
    from cuikslam.online import session as session_module

    log, _ = simulate_paper(seed=0)
    sessions = {level: Session(consistency=level, work_per_pose=1) for level in ("hull", "lp")}
    for session in sessions.values():
        for record in log.records:
            session.add(record)
        session.finish()
    assert sessions["hull"].settle() is True

    def boxes(session: Session) -> np.ndarray:
        return np.array([session.pose_box(pose) for pose in log.pose_ids])

    def bounds(session: Session) -> np.ndarray:
        n = session._grown.n_variables
        return np.stack([session._grown.lo[:n], session._grown.hi[:n]])

    hull = boxes(sessions["hull"])
    lp = sessions["lp"]
    with monkeypatch.context() as patch:
        patch.setattr(session_module.time, "perf_counter", lambda: 100.0)
        assert lp.settle(until=100.0) is False  # no time left: nothing starts
        assert not np.array_equal(bounds(lp), bounds(sessions["hull"]))
        assert lp.settle(until=100.0 + 1.5 * session_module.WINDOW_MARGIN_S) is False
        assert np.array_equal(bounds(lp), bounds(sessions["hull"]))  # hull's, no window
    assert lp.settle() is True
    widths_hull, widths_lp = np.diff(hull).squeeze(-1), np.diff(boxes(lp)).squeeze(-1)
    assert np.all(widths_lp <= widths_hull) and np.sum(widths_lp < widths_hull) > 0


def test_a_session_has_the_levels_hull_and_lp_only() -> None:
    with pytest.raises(ValueError, match="hull or lp"):
        Session(consistency="lp-split")


def test_the_last_pose_is_as_narrow_as_the_batch_solve() -> None:
    """On a 300-pose random world the last box is within 1 % of the batch hull box."""
    log, _ = simulate_random_world(seed=3, n_poses=300, n_landmarks=30)
    session = Session()
    for record in log.records:
        session.add(record)
    last = session.finish()
    graph = KinematicGraph.from_log(log)
    batch = propagate(graph).pose_box(last.pose)
    online, offline = np.diff(last.box).ravel(), np.diff(batch).ravel()
    assert np.all(np.isfinite(offline))
    assert np.all(online <= 1.01 * offline), (online, offline)


# --- the growing arrays ----------------------------------------------------------------------


def test_growing_arrays_narrow_bit_for_bit_like_the_batch_graph() -> None:
    """Grown past several capacities, all factors woken in order: the batch's iteration."""
    log, _ = simulate_random_world(seed=1, n_poses=200, n_landmarks=20)
    graph = KinematicGraph.from_log(log)
    grown = GrowingGraph(rtol=1e-3)
    lo, hi = graph.domains()
    for first in range(0, len(lo), 7):
        grown.add_variables(lo[first : first + 7], hi[first : first + 7])
    table = graph.factor_table()
    for first in range(0, len(table), 5):
        grown.add_factors(table[first : first + 5])
    assert len(grown.factors) > 256 and grown.n_factors == len(table)
    result = grown.narrow(np.arange(len(table)))
    batch = propagate(graph)
    assert result.status is Status.CONSISTENT and len(result.deferred) == 0
    assert result.applications == batch.applications
    assert np.array_equal(grown.lo[: len(lo)], batch.lo)
    assert np.array_equal(grown.hi[: len(hi)], batch.hi)


def test_the_arrays_grow_ahead_of_the_records_when_there_is_time() -> None:
    """``settle`` doubles arrays more than 3/4 full, so that a record seldom waits for it,
    and a graph grown so narrows bit for bit like the batch graph."""
    log, _ = simulate_random_world(seed=1, n_poses=150, n_landmarks=20)
    session = Session()
    for record in log.records:
        session.add(record)
        assert session.settle() is True and not session._grown.nearly_full
    assert session._grown.n_factors > 2 * 256  # past two capacities
    graph = KinematicGraph.from_log(log)
    grown = GrowingGraph(rtol=1e-3)
    grown.add_variables(*graph.domains())
    grown.add_factors(graph.factor_table())
    capacity = len(grown.factors)
    assert grown.nearly_full
    grown.grow()
    assert len(grown.factors) == 2 * capacity and not grown.nearly_full
    result = grown.narrow(np.arange(graph.n_factors))
    batch = propagate(graph)
    assert result.status is Status.CONSISTENT and result.applications == batch.applications
    n = graph.n_variables
    assert np.array_equal(grown.lo[:n], batch.lo) and np.array_equal(grown.hi[:n], batch.hi)


def test_work_left_by_a_limit_is_resumed_to_the_fixpoint() -> None:
    """Narrowing 50 applications at a time, from what each call deferred, ends at a
    fixpoint: waking every factor afterwards applies each once and wakes nobody."""
    log, _ = simulate_random_world(seed=2, n_poses=100, n_landmarks=20)
    graph = KinematicGraph.from_log(log)
    grown = GrowingGraph(rtol=1e-3)
    grown.add_variables(*graph.domains())
    grown.add_factors(graph.factor_table())
    result = grown.narrow(np.arange(graph.n_factors), max_applications=50)
    calls = 1
    while len(result.deferred):
        assert result.status is Status.BUDGET_EXHAUSTED and result.applications == 50
        result = grown.narrow(result.deferred, max_applications=50)
        calls += 1
    assert calls > 10 and result.status is Status.CONSISTENT
    settled = grown.narrow(np.arange(graph.n_factors))
    assert settled.applications == graph.n_factors


@CI
@given(world=worlds())
def test_a_tiny_work_limit_per_pose_keeps_the_truth(world: World) -> None:
    """Three operator applications per pose, the rest deferred: every box still holds it."""
    log = named_world(world)
    session = Session(work_per_pose=3)
    estimates = [e for e in map(session.add, log.records) if e is not None]
    estimates.append(session.finish())
    assert session.refuted is None
    for estimate in estimates:
        assert pose_misses(estimate.box, world.truth, estimate.pose) == []


# --- following lines: pacing and lateness, on a clock of our own -----------------------------


class FakeClock:
    """A clock that only moves when the code sleeps or when ``work`` says so."""

    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


LINES = [
    '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0], "time": 10.0}',
    '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0], "distance": [1, 1], "time": 11.0}',
    '{"type": "observation", "pose": 1, "class": "c", "range": [1, 2], "landmark": "A", '
    '"time": 11.0}',
    '{"type": "odometry", "from": 1, "to": 2, "turn": [0, 0], "distance": [1, 1], "time": 11.5}',
]


def paced(work_s: float, rate: float) -> tuple[FollowReport, FakeClock, list[float]]:
    """Follow ``LINES`` at ``rate`` where every record takes ``work_s`` seconds to add."""
    clock = FakeClock()
    session = Session()
    added: list[float] = []
    add = session.add

    def slow_add(record, received=None):
        added.append(clock.now)
        clock.now += work_s
        return add(record, received=received)

    session.add = slow_add
    lines = ((n, text, clock.now) for n, text in enumerate(LINES, start=1))
    report = follow(lines, session, lambda e: None, rate=rate, clock=clock, sleep=clock.sleep)
    return report, clock, added


def test_records_are_fed_at_their_recorded_times() -> None:
    report, _, added = paced(work_s=0.0, rate=2.0)
    assert added == [1000.0, 1000.5, 1000.5, 1000.75]
    assert (report.instants, report.late, report.poses) == (3, 0, 3)
    assert report.lags_s == [0.0, 0.0, 0.0]


def test_a_session_slower_than_the_records_is_reported_behind() -> None:
    report, _, added = paced(work_s=0.3, rate=1.0)
    assert added[:2] == [1000.0, 1001.0]
    # the third record shares the second's stamp; the fourth fell due at 1001.5, while the
    # third was being added (done at 1001.6)
    assert report.late == 1 and report.worst_late_line == 4
    assert report.worst_late_s == pytest.approx(0.1)
    assert report.lags_s == pytest.approx([0.0, 0.0, 0.1])


def test_pacer_keeps_time_stamps_that_go_back_at_the_latest() -> None:
    pacer = Pacer(rate=1.0)
    assert [pacer.due(t, now=0.0) for t in (None, 3.0, 2.0, None, 4.0)] == [0, 0, 0, 0, 1]


def test_log_lines_waits_for_a_growing_file_and_its_unfinished_line(tmp_path) -> None:
    """The line the writer has not finished is taken whole, once it is."""
    path = tmp_path / "growing.jsonl"
    path.write_text("a\nb", encoding="utf-8")

    def finish_the_line() -> None:
        time.sleep(0.2)
        with open(path, "a", encoding="utf-8") as writer:
            writer.write("c\nd\n")

    writer = threading.Thread(target=finish_the_line)
    writer.start()
    with open(path, encoding="utf-8") as stream:
        lines = [(n, text) for n, text, _ in log_lines(stream, wait=2.0)]
    writer.join()
    assert lines == [(1, "a\n"), (2, "bc\n"), (3, "d\n")]


def test_follow_refuses_an_input_without_records() -> None:
    with pytest.raises(InputFileError, match="the log is empty"):
        follow(iter([(1, "# nothing", 0.0)]), Session(path="x.jsonl"), lambda e: None)


def test_time_stamps_are_read_and_written_but_never_compared() -> None:
    [record] = parse_log_lines([LINES[0]]).records
    assert record.time == 10.0
    assert record == PosePrior(0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), line=1)
    from cuikslam.log.writer import log_to_lines

    assert '"time": 10.0' in log_to_lines(parse_log_lines([LINES[0]]))[0]
