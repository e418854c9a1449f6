"""``cuikslam warm-up``: compile every kernel into numba's on-disk cache, once, after an install.

Without a cache the first command compiles the kernels itself (about a hundred; about
20 s of CPU, see ``docs/benchmarks.md``) and the later ones load them from the cache. A
wheel built from the source tree (``pip install .``) already holds the cache, compiled by
the build (``build_backend/``) with :func:`warm_part`; this command is for the other
cases: an editable install, ``NUMBA_CACHE_DIR`` set, a ``site-packages`` the user cannot
write (numba then caches in the user's folder), or a wheel built on another CPU or with
another numba (numba ignores such a cache and compiles). The kernels are in two parts:
the narrowing (the factors' fixpoint, the ``lp`` level, the witness check's interval
operations) and the correspondence search (its search, bisection and gating kernels);
``--jobs 2`` compiles them in two processes at once. That costs about a third more CPU
(both compile the interval core): measured on a busy machine it was slower (``docs/benchmarks.md``,
"Install and start-up"), it can only pay on two free cores.
It also byte-compiles the package's modules (``compileall``) where pip did not (an
editable install, or ``PYTHONDONTWRITEBYTECODE`` set): importing them from source costs
about 0.2 s a command.

``python -m cuikslam.cli.warm_up PART`` compiles one part (what the second process runs).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time

from cuikslam.cli._common import int_at_least

__all__ = [
    "COMPILE_NOTE_S",
    "PARTS",
    "add_warm_up_parser",
    "byte_compile",
    "cache_folder",
    "note_compiling",
    "run_warm_up",
    "warm_part",
]

PARTS = ("narrowing", "search")
"""The kernels, in two parts that compile independently."""
COMPILE_NOTE_S = 5.0
"""A solve whose warm-up took longer than this compiled its kernels: the command says so."""


def note_compiling(timings: dict[str, float]) -> None:
    """Say on stderr that this run compiled the kernels, when its warm-up took that long.

    Parameters
    ----------
    timings : dict
        ``Solution.timings`` (its ``warm_up_s``).
    """
    seconds = timings.get("warm_up_s", 0.0)
    if seconds > COMPILE_NOTE_S:
        print(
            f"cuikslam: this run compiled the kernels ({seconds:.0f} s); they are cached "
            "now, so later runs start at once (`cuikslam warm-up` does it right after "
            "installing)",
            file=sys.stderr,
        )


def warm_part(part: str) -> float:
    """Compile (or load from the cache) the kernels of one part; the seconds it took.

    Parameters
    ----------
    part : str
        ``"narrowing"`` (fixpoint, ``lp`` level, the witness check's interval operations,
        the online session's calls) or ``"search"`` (the correspondence search's kernels).

    Returns
    -------
    float
        Seconds spent compiling or loading.
    """
    if part not in PARTS:
        raise ValueError(f"unknown part {part!r}: one of {', '.join(PARTS)}")
    from cuikslam.solver import warm_up

    start = time.perf_counter()
    if part == "search":
        warm_up(True)
    else:
        warm_up(False, lp=True)
        from cuikslam.interval import ops
        from cuikslam.online.session import warm_up as warm_up_online

        warm_up_online()  # the session's own calls (cuikslam follow)

        ops.compile_all()  # compiled on first use otherwise (the witness check's, the API's)
    return time.perf_counter() - start


def cache_folder() -> str:
    """Where numba caches this installation's kernels, in words."""
    import cuikslam
    from cuikslam.narrowing._propagate import propagate_arrays

    path = str(propagate_arrays._cache._cache_path)
    package = os.path.dirname(os.path.abspath(cuikslam.__file__))
    if path.startswith(package):
        return f"the __pycache__ folders under {package}"
    return os.path.dirname(path)  # NUMBA_CACHE_DIR or the user's cache: a folder per module


def byte_compile() -> bool:
    """Write the package's ``.pyc`` files where they are missing or stale.

    Returns
    -------
    bool
        False when some could not be written (a read-only installation: pip wrote them).
    """
    import compileall

    import cuikslam

    folder = os.path.dirname(os.path.abspath(cuikslam.__file__))
    return bool(compileall.compile_dir(folder, quiet=2))


def run_warm_up(jobs: int = 1) -> int:
    """Compile every kernel into the cache, in ``jobs`` (1 or 2) processes; exit status.

    Parameters
    ----------
    jobs : int
        2 compiles the search's kernels in a second process while this one compiles the
        narrowing's; 1 compiles both here.

    Returns
    -------
    int
        0 on success, else the failed process' exit status.
    """
    start = time.perf_counter()
    byte_compile()
    child = None
    if jobs > 1:
        child = subprocess.Popen([sys.executable, "-m", "cuikslam.cli.warm_up", "search"])
    warm_part("narrowing")
    if child is not None:
        status = child.wait()
        if status != 0:
            print(
                f"cuikslam: error: compiling the search's kernels failed ({status})",
                file=sys.stderr,
            )
            return status
    warm_part("search")  # loads what the child compiled (or compiles it when jobs == 1)
    print(
        f"cuikslam's kernels are compiled and cached in {cache_folder()} "
        f"({time.perf_counter() - start:.1f} s); later commands load them from there"
    )
    return 0


_positive_int = int_at_least(1)


def add_warm_up_parser(sub: argparse._SubParsersAction) -> None:
    """The ``warm-up`` command (imports nothing heavy: every command builds it)."""
    p = sub.add_parser(
        "warm-up",
        help="compile the kernels into numba's cache once (after an editable install)",
        description="Compile every compiled kernel into numba's on-disk cache, so that the "
        "first real command after an install does not spend its time compiling. The cache "
        "is beside the package (or where NUMBA_CACHE_DIR points). `pip install .` already "
        "compiles it into the wheel; an editable install does not.",
    )
    p.add_argument(
        "--jobs",
        type=_positive_int,
        default=1,
        help="processes compiling at once (default 1; 2 pays only on two free cores)",
    )
    p.set_defaults(func=lambda args: run_warm_up(args.jobs))


if __name__ == "__main__":
    warm_part(sys.argv[1])
    sys.stdout.flush()
    os._exit(0)  # skips finalising numba and LLVM (a noticeable part of a second)
