"""The build hook that compiles the kernels into the wheel (build_backend/, "cache at install").

The fast tests run the hook's logic on a stand-in package whose "warm-up" writes fake
cache files (no numba, no pip); the slow one builds the real wheel with pip (a minute).
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
BACKEND = ROOT / "build_backend"


@pytest.fixture
def kc(monkeypatch):
    """The stdlib-only module of the hook (build_backend/cuikslam_kernel_cache.py)."""
    monkeypatch.syspath_prepend(str(BACKEND))
    import cuikslam_kernel_cache

    return cuikslam_kernel_cache


# A stand-in for the package in build/lib: its warm-up writes what numba would.
_FAKE_WARM_UP = """
import os
from pathlib import Path
PARTS = ("narrowing", "search")
def warm_part(part):
    if os.environ.get("FAKE_FAIL") == part:
        raise RuntimeError("compile error in " + part)
    cache = Path(__file__).parent / "__pycache__"
    cache.mkdir(exist_ok=True)
    (cache / f"warm_up.k_{part}-3.py311.nbi").write_text(os.environ.get("NUMBA_CACHE_DIR", "-"))
    (cache / f"warm_up.k_{part}-3.py311.1.nbc").write_text(part)
"""


def fake_build_lib(root: Path) -> Path:
    """A build directory holding a stand-in ``cuikslam`` package."""
    cli = root / "lib" / "cuikslam" / "cli"
    cli.mkdir(parents=True)
    (cli.parent / "__init__.py").write_text("")
    (cli / "__init__.py").write_text("")
    (cli / "warm_up.py").write_text(_FAKE_WARM_UP)
    return root / "lib"


def test_compiles_except_for_editable_installs_or_when_opted_out(kc) -> None:
    assert kc.should_compile(False, {}) == (True, "")
    editable, why = kc.should_compile(True, {})
    assert not editable and "editable" in why
    for value in ("0", "no", "False", " off "):
        assert not kc.should_compile(False, {kc.OPT_OUT: value})[0]
    assert kc.should_compile(False, {kc.OPT_OUT: "1"})[0]


def test_build_requirements_are_the_projects_own_pins(kc) -> None:
    pyproject = ROOT / "pyproject.toml"
    wanted = kc.kernel_requirements(pyproject, {})
    dependencies = tomllib.loads(pyproject.read_text())["project"]["dependencies"]
    assert sorted(r.split(">")[0] for r in wanted) == sorted(kc.KERNEL_PACKAGES)
    assert all(r in dependencies for r in wanted)
    assert kc.kernel_requirements(pyproject, {kc.OPT_OUT: "0"}) == []


def test_the_project_builds_with_the_hook() -> None:
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert config["build-system"]["build-backend"] == "cuikslam_build"
    assert config["build-system"]["backend-path"] == ["build_backend"]
    assert config["tool"]["setuptools"]["cmdclass"]["build_py"] == "cuikslam_build.BuildPy"
    assert "build_backend/*.py" in (ROOT / "MANIFEST.in").read_text()  # in the sdist


def test_the_child_imports_the_copy_and_writes_beside_it(kc, tmp_path) -> None:
    env = {"PYTHONPATH": "/isolated/overlay", "NUMBA_CACHE_DIR": "/elsewhere", "HOME": "/h"}
    child = kc.warm_up_env(tmp_path, env)
    assert "NUMBA_CACHE_DIR" not in child
    assert child["PYTHONPATH"].split(":") == [str(tmp_path.resolve()), "/isolated/overlay"]
    assert child["PYTHONDONTWRITEBYTECODE"] == "1" and child["HOME"] == "/h"


def test_cache_files_are_compiled_into_the_build_directory(kc, tmp_path) -> None:
    build_lib = fake_build_lib(tmp_path)
    stale = build_lib / "cuikslam" / "__pycache__" / "old.f-1.py311.nbi"
    stale.parent.mkdir()
    stale.write_text("a previous build's")
    ok, message = kc.compile_kernels(build_lib, {"NUMBA_CACHE_DIR": str(tmp_path / "nc")})
    assert ok, message
    names = [p.name for p in kc.cache_files(build_lib)]
    assert names == sorted(
        f"warm_up.k_{part}-3.py311.{ext}"
        for part in ("narrowing", "search")
        for ext in ("nbi", "1.nbc")
    )
    assert "4 cache files" in message
    index = build_lib / "cuikslam" / "cli" / "__pycache__" / "warm_up.k_search-3.py311.nbi"
    assert index.read_text() == "-"  # NUMBA_CACHE_DIR did not reach the child
    assert not (tmp_path / "nc").exists()


def test_a_failed_compilation_builds_the_wheel_without_a_cache(kc, tmp_path) -> None:
    build_lib = fake_build_lib(tmp_path)
    ok, message = kc.compile_kernels(build_lib, {"FAKE_FAIL": "search"})
    assert not ok
    assert "exit status 1" in message and "compile error in search" in message
    assert kc.cache_files(build_lib) == []  # the narrowing's files are removed too


def test_a_missing_interpreter_does_not_raise(kc, tmp_path) -> None:
    ok, message = kc.compile_kernels(fake_build_lib(tmp_path), {}, python=str(tmp_path / "no"))
    assert not ok and "no compiled kernels" in message


def test_another_installation_shadowing_the_copy_is_refused(kc, tmp_path) -> None:
    # Nothing to import in the build directory: the child finds the tested cuikslam.
    empty = tmp_path / "lib"
    (empty / "cuikslam").mkdir(parents=True)
    ok, message = kc.compile_kernels(empty, {"PYTHONPATH": str(ROOT / "src")})
    assert not ok and "exit status 3" in message and "not from the build directory" in message


def test_build_py_compiles_only_outside_editable_mode(monkeypatch, tmp_path) -> None:
    pytest.importorskip("setuptools.build_meta")
    monkeypatch.syspath_prepend(str(BACKEND))
    import cuikslam_build
    from setuptools import Distribution

    calls = []
    monkeypatch.setattr(
        cuikslam_build.kernel_cache,
        "compile_kernels",
        lambda build_lib, env: calls.append(build_lib) or (True, "compiled"),
    )
    monkeypatch.delenv("CUIKSLAM_BUILD_KERNEL_CACHE", raising=False)
    for editable in (True, False):
        command = cuikslam_build.BuildPy(Distribution({"name": "x", "packages": []}))
        command.build_lib = str(tmp_path)
        command.ensure_finalized()
        command.editable_mode = editable
        command.run()
    assert calls == [tmp_path]


@pytest.mark.slow
def test_pip_builds_a_wheel_holding_the_compiled_kernels(tmp_path) -> None:
    """The real build (about a minute): the wheel lists numba's cache files in RECORD."""
    source = tmp_path / "src"
    ignore = shutil.ignore_patterns("__pycache__", "*.nb[ic]", "*.egg-info")
    for name in ("src", "build_backend"):
        shutil.copytree(ROOT / name, source / name, ignore=ignore)
    for name in ("pyproject.toml", "MANIFEST.in", "README.md"):
        shutil.copy(ROOT / name, source / name)
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(tmp_path), str(source)],
        check=True,
        timeout=900,
    )
    (wheel,) = tmp_path.glob("cuikslam-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        (record,) = (n for n in names if n.endswith(".dist-info/RECORD"))
        listed = {line.split(",")[0] for line in archive.read(record).decode().splitlines()}
    cached = {n for n in names if n.endswith((".nbi", ".nbc"))}
    assert any(n.startswith("cuikslam/narrowing/__pycache__/_propagate.") for n in cached)
    assert any("/hypotheses/__pycache__/" in n for n in cached)
    assert cached <= listed
    assert not any(n.endswith(".pyc") for n in names)
