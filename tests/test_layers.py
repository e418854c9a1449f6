"""The layers run one way: log → graph → narrowing → search → results, figures, CLI.

The search (``cuikslam.hypotheses``), the certification (``cuikslam.witness``), what a
solve returns (``cuikslam.outcome``) and everything below them never import the
presentation layer (``cuikslam.results``: files, tables, figures, the truth verdict) nor
the command line, not even inside a function: each module's imports are read from its
source (``ast``), so a lazy import counts too (docs/architecture.md).
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

import cuikslam

SRC = Path(cuikslam.__file__).resolve().parent

LOWER = ("hypotheses", "witness", "outcome", "narrowing", "graph", "log", "interval")
"""Packages below the presentation layer (directories of ``src/cuikslam``)."""
UPPER = ("cuikslam.results", "cuikslam.cli", "cuikslam.figures")
"""What they must not import."""
ALLOWED: dict[str, set[str]] = {}
"""Exceptions, module -> upper modules it may import, each with its reason. None today."""


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """Every module ``path`` imports (see :func:`_imports_of`)."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    return _imports_of(path.read_text(encoding="utf-8"), package)


def _imports_of(source: str, package: str) -> set[str]:
    """Every module ``source`` (a module of ``package``) imports, anywhere in it (relative
    imports made absolute; ``from cuikslam import results`` counts as ``cuikslam.results``)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")
                base = base[: len(base) - node.level + 1]
                module = ".".join([*base, *([node.module] if node.module else [])])
            else:
                module = node.module or ""
            found.add(module)
            found.update(f"{module}.{alias.name}" for alias in node.names)
    return found


def _lower_modules() -> list[Path]:
    return sorted(p for package in LOWER for p in (SRC / package).rglob("*.py"))


def _is_upper(module: str) -> bool:
    return any(module == u or module.startswith(u + ".") for u in UPPER)


def test_the_lower_packages_exist() -> None:
    for package in LOWER:
        assert (SRC / package / "__init__.py").is_file(), package
    assert len(_lower_modules()) > 50


@pytest.mark.parametrize("path", _lower_modules(), ids=_module_name)
def test_no_lower_module_imports_the_presentation_layer(path: Path) -> None:
    name = _module_name(path)
    upward = {m for m in _imports(path) if _is_upper(m)} - ALLOWED.get(name, set())
    assert not upward, f"{name} imports {sorted(upward)}"


def test_the_reader_sees_relative_and_lazy_imports() -> None:
    """The check itself: it sees an import inside a function, and a relative one."""
    source = "def f():\n    from ..results import io\n    import cuikslam.cli.main\n"
    found = {m for m in _imports_of(source, "cuikslam.hypotheses") if _is_upper(m)}
    assert found == {"cuikslam.results", "cuikslam.results.io", "cuikslam.cli.main"}
    assert "cuikslam.results" in _imports_of("from cuikslam import results", "cuikslam.log")


def test_importing_the_search_loads_no_presentation_module() -> None:
    """Transitively too: importing the search, the certification and the outcome types
    (in a fresh interpreter) loads no module of the presentation layer or the CLI."""
    code = (
        "import sys, cuikslam.hypotheses.search, cuikslam.hypotheses.finish, "
        "cuikslam.hypotheses.distributed, cuikslam.witness, cuikslam.outcome.summary, "
        "cuikslam.outcome.naming\n"
        f"print(sorted(m for m in sys.modules if m.startswith({UPPER!r})))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"


def test_the_old_homes_still_import() -> None:
    """``cuikslam.results.solution``, ``.summary``, ``.association`` and
    ``cuikslam.hypotheses.witness`` re-export the moved names (existing code, pickles)."""
    import cuikslam.hypotheses.witness.fit as old_fit

    import cuikslam.witness.fit as new_fit
    from cuikslam.hypotheses.witness import certify
    from cuikslam.outcome import naming, solution, summary
    from cuikslam.results import association
    from cuikslam.results import solution as old_solution
    from cuikslam.results import summary as old_summary
    from cuikslam.witness import certify as new_certify

    assert old_fit is new_fit and certify is new_certify
    for name in old_solution.__all__:
        assert getattr(old_solution, name) is getattr(solution, name)
    for name in old_summary.__all__:
        assert getattr(old_summary, name) is getattr(summary, name)
    for name in naming.__all__:
        assert getattr(association, name) is getattr(naming, name)
    assert cuikslam.Solution is solution.Solution and cuikslam.summarize is summary.summarize
