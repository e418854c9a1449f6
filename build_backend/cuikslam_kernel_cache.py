"""Compile cuikslam's numba kernels into the wheel while it is built ("cache at install").

numba's on-disk cache (``__pycache__/*.nbi`` index and ``*.nbc`` data files beside each
module) is keyed on a SHA-256 of the module's source and on the CPU (target triple, CPU
name and features), not on the file's path or time. So kernels compiled in the build
directory (``build/lib``) on the machine that installs the wheel are valid in
``site-packages`` after ``pip install .``: the first command after the install loads them
instead of compiling them (about 20 s of CPU). On another CPU, or with another numba,
numba ignores them and compiles as it would without them.

This module is stdlib only (the test suite imports it without setuptools); the
``build_py`` command that calls it is in ``cuikslam_build``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import tomllib
from collections.abc import Mapping
from pathlib import Path

__all__ = [
    "CACHE_PATTERNS",
    "KERNEL_PACKAGES",
    "OPT_OUT",
    "cache_files",
    "clear_cache_files",
    "compile_kernels",
    "kernel_requirements",
    "should_compile",
    "warm_up_env",
]

OPT_OUT = "CUIKSLAM_BUILD_KERNEL_CACHE"
"""Environment variable: ``0`` builds the wheel without compiled kernels."""
CACHE_PATTERNS = ("*.nbi", "*.nbc")
"""numba's cache files: an index per function, a data file per compiled signature."""
KERNEL_PACKAGES = ("numpy", "numba", "scipy", "highspy")
"""What compiling the kernels imports (``cuikslam.solver`` and the ``lp`` level)."""
TIMEOUT_S = 900.0
"""The compilation takes about 25 s on one core; past this it is abandoned."""

# Runs in the child, on the copy in the build directory. Exit status 3: cuikslam was
# imported from somewhere else (another installation shadows the copy).
_CHILD = """
import os, sys
import cuikslam
here = os.path.dirname(os.path.abspath(cuikslam.__file__))
if os.path.dirname(here) != os.path.abspath(sys.argv[1]):
    print(f"cuikslam imported from {here}, not from the build directory", file=sys.stderr)
    sys.exit(3)
from cuikslam.cli.warm_up import PARTS, warm_part
for part in PARTS:
    warm_part(part)
sys.stdout.flush()
os._exit(0)
"""


def should_compile(editable: bool, env: Mapping[str, str]) -> tuple[bool, str]:
    """Whether a build compiles the kernels into the wheel, and why not when it does not.

    Parameters
    ----------
    editable : bool
        ``build_py``'s ``editable_mode``: an editable install runs the sources in place,
        whose own ``__pycache__`` numba fills (``cuikslam warm-up`` does it at once).
    env : Mapping[str, str]
        The build's environment; ``CUIKSLAM_BUILD_KERNEL_CACHE=0`` opts out (a wheel built
        for other machines: its kernels would only fit this CPU).

    Returns
    -------
    tuple of (bool, str)
        True and ``""``, or False and the reason in words.
    """
    if editable:
        return False, "an editable install compiles in place (`cuikslam warm-up`)"
    if env.get(OPT_OUT, "").strip().lower() in ("0", "no", "false", "off"):
        return False, f"{OPT_OUT}={env[OPT_OUT]}"
    return True, ""


def kernel_requirements(pyproject: Path, env: Mapping[str, str]) -> list[str]:
    """The build requirements of the compilation: ``[project]``'s own pins of its packages.

    Parameters
    ----------
    pyproject : Path
        The project's ``pyproject.toml``; the lower bounds are those of its dependencies.
    env : Mapping[str, str]
        The build's environment (no requirements when the compilation is opted out).

    Returns
    -------
    list of str
        Requirement strings, e.g. ``["numpy>=1.26", "numba>=0.60", ...]``.
    """
    if not should_compile(False, env)[0]:
        return []
    dependencies = tomllib.loads(pyproject.read_text(encoding="utf-8"))["project"]
    wanted = []
    for requirement in dependencies["dependencies"]:
        name = re.split(r"[\s\[<>=!~;]", requirement, maxsplit=1)[0].lower()
        if name in KERNEL_PACKAGES:
            wanted.append(requirement)
    return wanted


def cache_files(build_lib: Path) -> list[Path]:
    """numba's cache files under ``build_lib``'s ``cuikslam`` package, sorted.

    Parameters
    ----------
    build_lib : Path
        The build directory the package was copied to (``build/lib``).

    Returns
    -------
    list of Path
    """
    package = Path(build_lib) / "cuikslam"
    return sorted(p for pattern in CACHE_PATTERNS for p in package.rglob(pattern))


def clear_cache_files(build_lib: Path) -> int:
    """Delete the cache files under ``build_lib`` (a previous build's); how many there were.

    Parameters
    ----------
    build_lib : Path
        The build directory.

    Returns
    -------
    int
    """
    files = cache_files(build_lib)
    for path in files:
        path.unlink()
    return len(files)


def warm_up_env(build_lib: Path, env: Mapping[str, str]) -> dict[str, str]:
    """The compiling child's environment: the build directory first on ``PYTHONPATH``.

    ``PYTHONPATH`` keeps what pip's isolated build environment put there (its
    ``sitecustomize``). ``NUMBA_CACHE_DIR`` is dropped, or numba would write the kernels
    there instead of beside the modules; ``PYTHONDONTWRITEBYTECODE`` keeps ``.pyc`` files
    out of the wheel (pip compiles them at install).

    Parameters
    ----------
    build_lib : Path
        The build directory.
    env : Mapping[str, str]
        The build's environment.

    Returns
    -------
    dict
    """
    child = {k: v for k, v in env.items() if k != "NUMBA_CACHE_DIR"}
    paths = [str(Path(build_lib).resolve()), *filter(None, [env.get("PYTHONPATH")])]
    child["PYTHONPATH"] = os.pathsep.join(paths)
    child["PYTHONDONTWRITEBYTECODE"] = "1"
    return child


def compile_kernels(
    build_lib: Path, env: Mapping[str, str], python: str = sys.executable
) -> tuple[bool, str]:
    """Compile every kernel of the copy in ``build_lib``, in a child process.

    Never raises: on failure (numba missing, a compile error, a timeout) it removes what
    was written and says why, and the wheel is built without compiled kernels.

    Parameters
    ----------
    build_lib : Path
        The build directory holding the ``cuikslam`` package's copy.
    env : Mapping[str, str]
        The build's environment.
    python : str
        The interpreter (the build's: the one that will run the installed package).

    Returns
    -------
    tuple of (bool, str)
        Success, and a line for the build's log.
    """
    clear_cache_files(build_lib)
    argv = [python, "-c", _CHILD, str(Path(build_lib).resolve())]
    try:
        done = subprocess.run(
            argv,
            env=warm_up_env(build_lib, env),
            capture_output=True,
            text=True,
            timeout=TIMEOUT_S,
            check=False,
        )
        failure = f"exit status {done.returncode}: {done.stderr.strip()[-800:]}"
        ok = done.returncode == 0
    except (OSError, subprocess.SubprocessError) as error:
        ok, failure = False, str(error)
    files = cache_files(build_lib)
    if ok and files:
        size = sum(p.stat().st_size for p in files) / 1e6
        return True, f"compiled kernels: {len(files)} cache files ({size:.1f} MB)"
    clear_cache_files(build_lib)
    why = failure if not ok else "no cache file was written"
    return False, f"the wheel has no compiled kernels ({why})"
