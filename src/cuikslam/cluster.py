"""Dask clusters for cuikslam: a client (a local cluster or an existing one), and a batch
of logs solved one per task.

Dask is optional (``pip install "cuikslam[distributed]"``) and imported only when a
cluster is asked for; without it :func:`dask_client` raises :class:`DaskMissingError`,
whose message says what to install. A correspondence search on the cluster is
:func:`cuikslam.hypotheses.distributed.search_distributed`.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any

from cuikslam.options import SolveOptions

if TYPE_CHECKING:
    from cuikslam.log.records import Log
    from cuikslam.outcome.solution import Solution

__all__ = ["INSTALL_HINT", "DaskMissingError", "dask_client", "solve_batch"]

INSTALL_HINT = 'needs Dask, which is not installed: pip install "cuikslam[distributed]"'


class DaskMissingError(ImportError):
    """A cluster was asked for and Dask is not installed."""


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise DaskMissingError(f"a Dask cluster {INSTALL_HINT}") from None
    return distributed


def _warm_worker() -> float:
    from cuikslam.solver import warm_up

    return warm_up(True)


@contextmanager
def dask_client(
    workers: int | None = None, scheduler: str | None = None, processes: bool = True
) -> Iterator[Any]:
    """A :class:`distributed.Client`: of the cluster at ``scheduler``, or of a local
    cluster of ``workers`` single-threaded workers (processes, or threads of this process
    with ``processes=False``), closed on exit. Every worker loads the compiled kernels
    first. Raises :class:`DaskMissingError` without Dask."""
    distributed = _distributed()
    cluster = None
    if scheduler is not None:
        client = distributed.Client(scheduler)
    else:
        cluster = distributed.LocalCluster(
            n_workers=workers or 1, threads_per_worker=1, processes=processes,
            dashboard_address=":0",
            # threads share one process: a per-worker memory limit would pause them all
            memory_limit="auto" if processes else 0,
        )  # fmt: skip
        client = distributed.Client(cluster)
    try:
        client.run(_warm_worker)
        yield client
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def solve_batch(
    logs: Sequence[Log],
    client: Any,
    options: SolveOptions | None = None,
    **overrides: Any,
) -> list[Solution]:
    """Solve every log of ``logs`` on ``client``'s workers, one task per log.

    Parameters
    ----------
    logs : sequence of Log
        The logs.
    client : distributed.Client
        The cluster (see :func:`dask_client`).
    options : SolveOptions, optional
        The options of every solve (see :func:`cuikslam.solver.solve`).
    **overrides
        Fields of :class:`~cuikslam.options.SolveOptions` replacing those of ``options``.

    Returns
    -------
    list of Solution
        One per log, in the order of ``logs``.

    Examples
    --------
    Two seeds of the paper's experiment on two threads of this process:

    >>> import cuikslam
    >>> worlds = [cuikslam.simulate_paper(seed=seed) for seed in (0, 1)]
    >>> with dask_client(workers=2, processes=False) as client:
    ...     solutions = solve_batch([log for log, _ in worlds], client, consistency="hull")
    >>> [cuikslam.check_truth(solution.best, truth.pose_ids, truth.exact_poses()).ok
    ...  for solution, (_, truth) in zip(solutions, worlds)]
    [True, True]
    """
    from cuikslam.solver import solve

    options = SolveOptions.merged(options, overrides, "solve_batch")
    futures = [client.submit(solve, log, options, pure=False) for log in logs]
    return client.gather(futures)
