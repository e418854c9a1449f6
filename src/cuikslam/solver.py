"""Solve a log: build its kinematic graph(s), narrow them, return the surviving hypotheses.

Known correspondence (every observation names its landmark) gives one graph; otherwise
the hypothesis search of :mod:`cuikslam.hypotheses` branches over correspondences.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import Any

from cuikslam._fpu import ensure_round_to_nearest
from cuikslam.budget import SCHEDULE, Budget
from cuikslam.graph.kinematic_graph import KinematicGraph
from cuikslam.hypotheses.dive import ProofStage
from cuikslam.hypotheses.labelled import (
    has_labelled_logs,
    hypothesis_from_graph,
    solve_labelled,
)
from cuikslam.hypotheses.search import solve_unknown
from cuikslam.log.reader import reject_reserved_landmark_id
from cuikslam.log.records import Log
from cuikslam.messages import Message
from cuikslam.narrowing.consistency import StrengthenReport, strengthen
from cuikslam.narrowing.outliers import RelaxedReport, narrow_with_outliers
from cuikslam.narrowing.propagation import DEFAULT_ROUNDS, Arrays, propagate
from cuikslam.options import Level, SolveOptions
from cuikslam.outcome.solution import Solution
from cuikslam.outliers import (
    certify_without_outliers,
    hypothesis_outlier_messages,
    outlier_messages,
    outlier_scope,
    outliers_to_json,
)
from cuikslam.witness import certify, fit_hypotheses

__all__ = ["budget_message", "hypothesis_from_graph", "solve"]

ProgressCallback = Callable[[int, int], None]
"""Called with (done, total) as a long solve advances."""

CERTIFY_MAX_POSES = 2000
"""No witness search beyond this many poses. The search minimises in a sparse form
(:mod:`cuikslam.witness._world`), whose evaluations grow with the log (a
200-pose world proven in 0.2 s, 1,000 poses in 0.7 s, 2,000 in 2.7 s of CPU, 250 MB), but
a log with loop-closing odometry polishes its closures and picks its verification's pivots
on the model's dense Jacobian (frames x parameters: 0.2 GB at 2,000 poses). Within the cap
the work budget (or, without one, the witness' evaluation limit) bounds the search."""


_WARM_UP_LOG = [
    '{"type": "sensor", "max_range": 5.0, "fov": 3.0}',
    '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}',
    '{"type": "observation", "pose": 0, "class": "c", "range": [1, 1.1], "bearing": [0, 0.1]}',
    '{"type": "odometry", "from": 0, "to": 1, "turn": [0, 0.1], "distance": [1, 1.1]}',
    '{"type": "observation", "pose": 1, "class": "c", "range": [0, 0.2], "bearing": [0, 0.1]}',
    '{"type": "observation", "pose": 1, "class": "c", "range": [2, 2.1], "landmark": "A"}',
]
_warmed_up: set[bool | str] = set()
"""The kinds of log (unknown correspondence or not) whose kernels are loaded."""


def warm_up(unknown: bool = True, lp: bool = False) -> float:
    """Compile (or load from numba's cache) the kernels a solve uses, once per process.

    Runs before the budget starts, so that the first solve after installing cuikslam
    spends its budget on the log rather than on compiling. ``unknown`` also loads the
    correspondence search's kernels, which a known-correspondence solve does not use
    (quick from numba's cache, far longer to compile on a first run). ``lp`` also loads
    the kernels of the ``lp`` level (:func:`cuikslam.narrowing.consistency.warm_up_lp`).
    Returns the seconds it took (0 when done before).
    """
    if lp and "lp" not in _warmed_up:
        from cuikslam.narrowing.consistency import warm_up_lp

        start = time.perf_counter()
        warm_up_lp()
        _warmed_up.add("lp")
        return time.perf_counter() - start + warm_up(unknown)
    if unknown in _warmed_up:
        return 0.0
    from cuikslam.log import parse_log_lines

    start = time.perf_counter()
    if unknown:
        solve_unknown(parse_log_lines(_WARM_UP_LOG), consistency="hull")
    known = KinematicGraph.from_log(
        parse_log_lines([*_WARM_UP_LOG[:2], *_WARM_UP_LOG[3:4], _WARM_UP_LOG[5]])
    )
    propagate(known)
    _warmed_up.add(unknown)
    return time.perf_counter() - start


def solve(
    log: Log,
    options: SolveOptions | None = None,
    *,
    progress: ProgressCallback | None = None,
    on_survivor: Callable[[list[str]], None] | None = None,
    search: Callable[..., Solution] | None = None,
    **overrides: Any,
) -> Solution:
    """Solve ``log`` and return every hypothesis that narrowing could not refute.

    With known correspondence there is one hypothesis, or none when the log is proven
    inconsistent (then ``Solution.refuted`` is True). When some observation names no
    landmark, the correspondence search of :func:`cuikslam.hypotheses.solve_unknown` runs.
    The ``certify_limit`` best-ranked hypotheses (all reported ones by default) are then
    certified: a solution point is searched and verified in interval arithmetic, making
    them *proven consistent* (the witness search is skipped beyond ``CERTIFY_MAX_POSES``
    poses).

    Parameters
    ----------
    log : Log
        The log (see :func:`cuikslam.log.read_log_file`).
    options : SolveOptions, optional
        The options (defaults: ``SolveOptions()``).
    progress : callable, optional
        Called with (done, total) as a long solve advances; with unknown correspondence,
        the readings decided of those to decide, and a
        :class:`~cuikslam.hypotheses.progress.SearchProgress` as a third argument when
        the callable takes one (see :func:`~cuikslam.hypotheses.solve_unknown`).
    on_survivor : callable, optional
        With unknown correspondence, called with the assignment of every survivor of the
        search as it is found (see :func:`~cuikslam.hypotheses.solve_unknown`): all of
        them, however many are reported.
    search : callable, optional
        Runs the correspondence search in place of
        :func:`~cuikslam.hypotheses.solve_unknown` (same parameters), e.g. on a cluster:
        ``functools.partial(search_distributed, client=client)``
        (:mod:`cuikslam.hypotheses.distributed`).
    **overrides
        Fields of :class:`~cuikslam.options.SolveOptions` (``consistency``,
        ``max_hypotheses``, ``strengthen_limit``, ``strengthen_during``,
        ``certify_limit``, ``rtol``, ``work_budget``, ``time_budget``, ``threads``,
        ``max_nodes``, ``local_frame``) replacing those of ``options``.

    Returns
    -------
    Solution
        The surviving hypotheses, best-ranked first, with statistics, timings and
        messages.

    Notes
    -----
    ``work_budget`` (work units, see :mod:`cuikslam.budget`) bounds the whole solve, so
    that the same log and options give the same result on any machine and at any load;
    ``time_budget`` (seconds) may cap it as well, and the result then records whether the
    clock bound (``statistics["budget_bound"]``). With known
    correspondence the fixpoint of the factors always runs to the end (it takes
    milliseconds); the stronger level may use its share of what is left, and the witness
    search the rest. With unknown correspondence the search gets its share of the budget;
    when it ends, the least-squares fit that ranks its survivors
    (:func:`~cuikslam.witness.fit_hypotheses`) may use its share of what is
    left, and the stronger level then narrows them in that order, within the search's
    share. The shares are :data:`cuikslam.budget.SCHEDULE`'s. A stage that runs out
    stops soundly and says so: the level actually reached (e.g. ``"lp (budget)"``, see
    :mod:`cuikslam.narrowing.consistency`) in ``Solution.consistency`` and each
    hypothesis' ``consistency``, a hypothesis left ``not refuted`` rather than proven, an
    incomplete search, each with a message in ``Solution.messages``.
    """
    options = SolveOptions.merged(options, overrides, "solve")
    reject_reserved_landmark_id(log)  # a log built in code has not met the reader's check
    ensure_round_to_nearest()
    unknown = log.has_unknown_correspondence
    lp = options.consistency is not Level.HULL or (unknown and options.strengthen_during != 0)
    warm_up_s = warm_up(unknown, lp)
    start = time.perf_counter()
    n_poses = len(log.pose_ids)
    reserve = options.walk_reserve_for(n_poses, unknown)
    deadline = Budget.start(options.work_for(n_poses, unknown), options.time_budget, reserve)
    if unknown:
        solution = (search or solve_unknown)(
            log,
            options,
            progress=progress,
            deadline=SCHEDULE.share(deadline, "search"),
            on_survivor=on_survivor,
            prove=(
                (
                    lambda h, stage: certify(
                        log, Solution([h]), deadline=_early_proof(deadline, stage)
                    )
                )
                if options.certify_limit != 0 and n_poses <= CERTIFY_MAX_POSES
                else None
            ),
            rank=lambda report: fit_hypotheses(
                log,
                report,
                SCHEDULE.share(deadline, "fit"),
                known=partial(solve_labelled, log, rtol=options.rtol, threads=options.threads)
                if has_labelled_logs(log)
                else None,
            ),
        )
    else:
        solution = _solve_known(log, options, progress, deadline)
    certify_limit = options.certify_limit
    if n_poses > CERTIFY_MAX_POSES and certify_limit != 0 and solution.hypotheses:
        certify_limit = 0  # see CERTIFY_MAX_POSES
        solution.messages.append(
            f"no witness search beyond {CERTIFY_MAX_POSES} poses (this log has {n_poses}): "
            "the hypotheses stay 'not refuted', neither proven consistent nor impossible"
        )
    certify_start = time.perf_counter()
    searched = False  # whether the witness search of the outliers record ran
    if log.outlier_bounds and certify_limit != 0:
        searched = certify_without_outliers(log, solution, certify, deadline)
        certify_limit = 0  # done: the witness leaves the proven outliers out
    if not searched:  # (with certify_limit 0, it only records zero counts)
        certified = replace(solution, hypotheses=solution.hypotheses[:certify_limit])
        certify(log, certified, deadline=deadline)
        solution.hypotheses[:certify_limit] = certified.hypotheses  # proven ones rank first
    if unknown and solution.outliers is not None:  # in the report's final order
        solution.messages.extend(outlier_messages(solution.outliers))
        solution.messages.extend(hypothesis_outlier_messages(log, solution))
    solution.timings["certify_s"] = time.perf_counter() - certify_start
    solution.timings["total_s"] = time.perf_counter() - start
    solution.timings["warm_up_s"] = warm_up_s
    if options.time_budget is not None:
        solution.timings["time_budget_s"] = float(options.time_budget)
    _record_budget(solution, deadline, reserve)
    return solution


def _early_proof(deadline: Budget | None, stage: ProofStage) -> Budget | None:
    """The budget of an early proof (``"early_proof"``, or ``"guess_proof"`` of it)."""
    early = SCHEDULE.share(deadline, "early_proof")
    return SCHEDULE.share(early, "guess_proof") if stage == "guess_proof" else early


def _record_budget(solution: Solution, budget: Budget, reserve: float) -> None:
    """Which budget the solve had (its walk's ``reserve`` included), what it spent and
    which limit stopped a stage, if any; a message when the wall clock did (the result may
    then differ from run to run)."""
    stats = solution.statistics
    stats["work_budget"] = None if budget.work == math.inf else budget.work + reserve
    stats["walk_reserve_spent"] = round(budget.meter.credit)
    stats["work_spent"] = round(budget.meter.spent)
    stats["budget_bound"] = budget.meter.bound
    if budget.meter.bound == "interrupt":
        solution.messages.append(
            "interrupted (Ctrl-C): every stage stopped where it was; the result holds what "
            "was proven by then (with unknown correspondence, the envelope holds the truth)"
        )
    if budget.meter.bound == "time":
        solution.messages.append(
            Message(
                "time_bound",
                "the wall-clock cap (time_budget) stopped a stage before its work budget: "
                "this result depends on how fast the machine ran, and may differ from run to run",
            )
        )


def _solve_known(
    log: Log, options: SolveOptions, progress: ProgressCallback | None, deadline: Budget | None
) -> Solution:
    start = time.perf_counter()
    consistency, rtol = options.consistency, options.rtol
    assignment = [str(o.landmark) for o in log.observations]
    graph = KinematicGraph.from_log(log)
    report = StrengthenReport(level=str(consistency))
    outliers = None
    if log.outlier_bounds:
        relaxed = RelaxedReport(strengthen=StrengthenReport(level="hull"))
        lo, hi = graph.domains()
        result = narrow_with_outliers(
            Arrays.of(graph), lo, hi, outlier_scope(log, graph), consistency, rtol,
            DEFAULT_ROUNDS, deadline=SCHEDULE.share(deadline, "strengthen"), report=relaxed,
            threads=options.threads,
        )  # fmt: skip
        report = relaxed.strengthen
        outliers = outliers_to_json(log, relaxed)
        branching = {
            "outlier_blocks": relaxed.branched_blocks,
            "outlier_sets": relaxed.branched_sets,
            "outlier_blocks_skipped": relaxed.skipped_blocks,
        }
    else:
        result = propagate(graph, rtol=rtol)
    if not result.is_empty and outliers is None:
        strengthened = strengthen(
            Arrays.of(graph), result.lo, result.hi, consistency, rtol, DEFAULT_ROUNDS,
            progress, deadline=SCHEDULE.share(deadline, "strengthen"), report=report,
            threads=options.threads,
        )  # fmt: skip
        result.applications += strengthened.applications
        result.status = strengthened.status
    if progress is not None:
        progress(1, 1)
    elapsed = time.perf_counter() - start
    statistics = {
        "poses": len(graph.pose_ids),
        "landmarks": len(graph.landmark_ids),
        "factors": graph.n_factors,
        "operator_applications": result.applications,
        "lp_rounds": report.lp_rounds,
        "lp_solved": report.lp.solved,
        "lp_limit_hits": report.lp.limit_hits,
        "lp_retries": report.lp.retries,
        "lp_skipped": report.lp.skipped,
        "lp_budget_exhausted": int(report.budget_exhausted),
    }
    messages = []
    if outliers is not None:
        statistics["outliers_proven"] = len(outliers["proven"])
        statistics.update(branching)
        messages.extend(outlier_messages(outliers))
    if report.budget_exhausted and not result.is_empty:
        messages.append(budget_message(consistency, report))
    if result.is_empty:
        if outliers is None:
            messages.append("the log is inconsistent: its constraints contract to empty (a proof)")
        return Solution(
            hypotheses=[],
            statistics=statistics,
            timings={"solve_s": elapsed},
            log_path=log.path,
            consistency=str(consistency),
            messages=messages,
            outliers=outliers,
        )
    hypothesis = hypothesis_from_graph(graph, result.lo, result.hi, assignment, report.level)
    return Solution(
        hypotheses=[hypothesis],
        statistics=statistics,
        timings={"solve_s": elapsed},
        log_path=log.path,
        consistency=report.level,
        messages=messages,
        outliers=outliers,
    )


def budget_message(level: Level | str, report: StrengthenReport) -> str:
    """The message of a stronger level cut short by its budget.

    Parameters
    ----------
    level : Level or str
        The level asked for.
    report : StrengthenReport
        What :func:`~cuikslam.narrowing.consistency.strengthen` reached.

    Returns
    -------
    str
        One sentence for ``Solution.messages``.
    """
    return (
        f"the budget ran out during the '{level}' level: the boxes reach level "
        f"'{report.level}' ({report.lp_rounds} polytope round(s), {report.lp.solved} LPs); "
        "they are sound, only wider than the full level would make them (a larger work "
        "budget, or none, reaches the full level)"
    )
