"""``class`` records: a user's priors on a class of landmarks, read strictly, used soundly.

The guarantee with class priors that hold in the true world is property-tested in
``test_guarantee.py`` (``test_class_priors_the_truth_meets_keep_it``)."""

from __future__ import annotations

import pytest

from cuikslam.errors import InputFileError
from cuikslam.hypotheses import solve_unknown
from cuikslam.log.reader import parse_log_lines
from cuikslam.log.records import ClassPrior, Log
from cuikslam.log.writer import log_to_lines
from cuikslam.simulate import simulate_paper
from cuikslam.solver import solve

PRIOR = '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}'


def test_class_record_reads_and_writes_back() -> None:
    line = (
        '{"type": "class", "class": "post", "at_most": 3, "min_separation": 1.5, '
        '"x": [-2, 12], "y": [-3, 8]}'
    )
    log = parse_log_lines([PRIOR, line])
    assert log.class_priors == {
        "post": ClassPrior("post", 3, 1.5, (-2.0, 12.0), (-3.0, 8.0), line=2)
    }
    again = parse_log_lines(log_to_lines(log))
    assert [(r.at_most, r.min_separation, r.x, r.y) for r in again.class_priors.values()] == [
        (3, 1.5, (-2.0, 12.0), (-3.0, 8.0))
    ]


@pytest.mark.parametrize(
    ("record", "message"),
    [
        ('{"type": "class", "class": "door"}', "needs at least one of"),
        ('{"type": "class", "class": "door", "at_most": 1.5}', '"at_most" must be a whole'),
        ('{"type": "class", "class": "door", "at_most": -1}', '"at_most" must be a whole'),
        ('{"type": "class", "class": "door", "at_most": true}', '"at_most" must be a whole'),
        ('{"type": "class", "class": "door", "min_separation": 0}', "must be positive"),
        ('{"type": "class", "class": "door", "x": [0, 1]}', '"x" and "y" come together'),
        ('{"type": "class", "class": "door", "x": [1, 0], "y": [0, 1]}', '"x"'),
        ('{"type": "class", "class": "door", "at_most": 2, "ratio": 1}', 'unknown field "ratio"'),
    ],
)
def test_bad_class_records_name_their_line(record: str, message: str) -> None:
    with pytest.raises(InputFileError) as caught:
        parse_log_lines([PRIOR, record], path="trip.jsonl")
    assert str(caught.value).startswith("trip.jsonl:2:")
    assert message in str(caught.value)


def test_a_second_record_for_a_class_is_rejected() -> None:
    lines = [PRIOR, '{"type": "class", "class": "door", "at_most": 2}']
    lines.append('{"type": "class", "class": "door", "min_separation": 1}')
    with pytest.raises(InputFileError, match=r":3: a second class record for \"door\""):
        parse_log_lines(lines)


def _with(log: Log, *priors: ClassPrior) -> Log:
    return Log(records=[*priors, *log.records], path=log.path)


def test_at_most_cuts_the_new_landmark_branches_of_the_seed_experiment() -> None:
    log, truth = simulate_paper(seed=0, unknown=True)
    doors = truth.landmark_classes.count("door")
    free = solve_unknown(log, consistency="hull")
    ruled = solve_unknown(_with(log, ClassPrior("door", at_most=doors)), consistency="hull")
    assert len(free.hypotheses) == 2
    assert [h.n_landmarks for h in ruled.hypotheses] == [4]
    assert ruled.complete and ruled.statistics["refuted_by_class_prior"] > 0
    first: dict[str, int] = {}
    mine: dict[str, int] = {}
    assert [first.setdefault(a, len(first)) for a in truth.assignment] == [
        mine.setdefault(a, len(mine)) for a in ruled.hypotheses[0].assignment
    ]


def test_named_landmarks_beyond_at_most_prove_the_log_inconsistent() -> None:
    log, _ = simulate_paper(seed=0)  # every observation named: 2 doors
    solution = solve_unknown(_with(log, ClassPrior("door", at_most=1)), consistency="hull")
    assert solution.complete and solution.hypotheses == []


def test_separation_refutes_two_landmarks_proven_too_close() -> None:
    """Two named doors whose boxes are within 0.5 m of each other, with a 1 m separation."""
    lines = [
        PRIOR,
        '{"type": "landmark", "id": "A", "class": "door", "x": [1, 1.2], "y": [0, 0.2]}',
        '{"type": "landmark", "id": "B", "class": "door", "x": [1.1, 1.3], "y": [0.1, 0.3]}',
        '{"type": "observation", "pose": 0, "class": "door", "range": [0.9, 1.4], '
        '"bearing": [-0.5, 0.5]}',
    ]
    log = parse_log_lines(lines)
    assert len(solve_unknown(log, consistency="hull").hypotheses) > 0
    sep = parse_log_lines([*lines, '{"type": "class", "class": "door", "min_separation": 1}'])
    assert solve_unknown(sep, consistency="hull").hypotheses == []
    wide = parse_log_lines([*lines, '{"type": "class", "class": "door", "min_separation": 0.4}'])
    assert len(solve_unknown(wide, consistency="hull").hypotheses) > 0


def test_region_bounds_landmarks_with_known_correspondence() -> None:
    log, _ = simulate_paper(seed=0)
    free = solve(log, consistency="hull", certify_limit=0).best
    region = ClassPrior("door", x=(-1.0, 31.0), y=(-1.0, 30.2))  # both doors, L3's top cut
    boxed = solve(_with(log, region), consistency="hull", certify_limit=0).best
    assert free.landmark("L3")[1, 1] > 30.2 >= boxed.landmark("L3")[1, 1]
    for lid in ("L1", "L3"):
        assert -1.0 <= boxed.landmark(lid)[1, 0] and boxed.landmark(lid)[1, 1] <= 30.2
    tight = ClassPrior("door", x=(14.0, 15.5), y=(-0.5, 0.5))  # leaves L3 no room
    assert solve(_with(log, tight), consistency="hull", certify_limit=0).refuted


def test_a_proven_hypothesis_meets_the_class_priors() -> None:
    """A witness must satisfy the class priors too (an adversarial tester's find: a new
    door 2e-16 from a known one was 'proven consistent' despite min_separation 2.9)."""
    from fractions import Fraction
    from pathlib import Path

    from cuikslam.log.reader import read_log_file
    from cuikslam.results.solution import PROVEN

    path = Path(__file__).parent / "data" / "found" / "min-separation-proven-wrong.jsonl"
    log = read_log_file(path)
    separation = Fraction(log.class_priors["door"].min_separation)
    proven = [h for h in solve(log, work_budget=3.5e6).hypotheses if h.status == PROVEN]
    assert proven
    for h in proven:
        xy = [tuple(map(Fraction, p)) for p in h.witness["landmarks_xy"]]
        for i in range(len(xy)):
            for j in range(i):
                gap2 = (xy[i][0] - xy[j][0]) ** 2 + (xy[i][1] - xy[j][1]) ** 2
                assert gap2 >= separation**2, (h.assignment, xy)
