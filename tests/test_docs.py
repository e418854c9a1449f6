"""The documentation says what runs: its commands run, its pages hold together.

A fenced block in the README or a page of ``docs/`` is run when the line before it is a
marker:

* ``<!-- docs-test: run -->``: a shell block (each line one ``cuikslam`` command) or a
  Python block, run here in one temporary folder shared by every page, a page's blocks in
  order; each command (run through ``cuikslam.cli.main.main``, the console script's
  function, in this process) must exit with status 0 and write the files its output
  options name;
* ``<!-- docs-test: slow -->``: the same, for commands that need real data or minutes
  (``python -m pytest -m slow``);
* ``<!-- docs-test: setup -->``: the README's set-up commands, exactly two: the first
  installs and runs the seed's experiment (its ``cuikslam`` part runs here), the second
  is the test command that ``.ci/run`` runs.
"""

from __future__ import annotations

import contextlib
import importlib
import io
import os
import re
import shlex
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from cuikslam.cli.main import main
from cuikslam.datasets import data_dir

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
MARKED = re.compile(r"^<!-- docs-test: (run|slow|setup) -->\n```(\w*)\n(.*?)^```", re.S | re.M)
OUTPUT_OPTIONS = ("-o", "--output", "--json", "--csv", "--figure", "--survivors")
"""Options whose value is a file the command writes."""
DEFAULT_OUTPUTS = {"paper": ["cuikslam-paper.png"]}
"""Files a command writes without being told where (the docs name them)."""
NEEDS = {"docs/api/index.md": ["docs/getting-started.md"]}
"""Pages whose blocks read files that the blocks of other pages write."""
DATA_FILES = {"dataset2.mat": "lost-in-the-woods/dataset2.mat"}
"""Real-data files the slow blocks name, under the data folder (``CUIKSLAM_DATA``)."""


@dataclass(frozen=True)
class Block:
    page: str
    kind: str
    """``run``, ``slow`` or ``setup``."""
    language: str
    text: str
    line: int

    def __str__(self) -> str:
        return f"{self.page}:{self.line}"


def blocks(page: Path) -> list[Block]:
    """The marked blocks of ``page``, in order."""
    text = page.read_text(encoding="utf-8")
    name = page.relative_to(ROOT).as_posix()
    return [
        Block(name, m[1], m[2], m[3], text.count("\n", 0, m.start()) + 2)
        for m in MARKED.finditer(text)
    ]


def pages() -> list[Path]:
    return [README, *sorted((ROOT / "docs").rglob("*.md"))]


ALL_BLOCKS = [b for page in pages() for b in blocks(page)]


def commands(block: Block) -> list[list[str]]:
    """The shell commands of a block: one a line, ``\\`` continuing a line, comments
    dropped; in a set-up block, the ``cuikslam`` parts of ``A && B`` chains."""
    joined = block.text.replace("\\\n", " ")
    found = []
    for line in joined.splitlines():
        for part in line.split("&&"):
            words = shlex.split(part, comments=True)
            if not words:
                continue
            if block.kind == "setup" and words[0] != "cuikslam":
                continue  # installing, and the test command itself, are CI's to run
            assert words[0] == "cuikslam", f"{block}: not a cuikslam command: {part.strip()}"
            found.append(words[1:])
    return found


def outputs(args: list[str]) -> list[str]:
    """The files a command says it writes."""
    named = [args[i + 1] for i, a in enumerate(args[:-1]) if a in OUTPUT_OPTIONS]
    if args and args[0] in DEFAULT_OUTPUTS and not any(a in OUTPUT_OPTIONS for a in args):
        named += DEFAULT_OUTPUTS[args[0]]
    return named


class Workspace:
    """One folder where the pages' blocks run, each page once, after the pages it needs."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.done: set[tuple[str, tuple[str, ...]]] = set()
        self.ran: set[tuple[str, ...]] = set()

    def run_page(self, page: str, kinds: tuple[str, ...] = ("run", "setup")) -> None:
        if (page, kinds) in self.done:
            return
        for need in NEEDS.get(page, []):
            self.run_page(need)
        for block in (b for b in ALL_BLOCKS if b.page == page and b.kind in kinds):
            if block.language == "python":
                self.run_python(block)
            else:
                for args in commands(block):
                    self.run_command(block, args)
        self.done.add((page, kinds))

    def run_command(self, block: Block, args: list[str]) -> None:
        """Run ``cuikslam ARGS`` through the command's own entry point, in this process
        (the kernels load once); a command run before, with the same words in the same
        folder, is not run again."""
        if tuple(args) in self.ran:
            return
        for name in outputs(args):
            (self.folder / name).unlink(missing_ok=True)
        shown = shlex.join(["cuikslam", *args])
        printed = io.StringIO()
        with _inside(self.folder), _environ(COLUMNS="220", NO_COLOR="1", MPLBACKEND="Agg"):
            with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
                status = main(args)
        assert status == 0, f"{block}: `{shown}` exited {status}:\n{printed.getvalue()[-4000:]}"
        for name in outputs(args):
            path = self.folder / name
            assert path.is_file() and path.stat().st_size > 0, f"{block}: `{shown}` wrote no {name}"
        self.ran.add(tuple(args))

    def run_python(self, block: Block) -> None:
        code = compile(block.text, str(block), "exec")
        with _inside(self.folder), contextlib.redirect_stdout(io.StringIO()):
            exec(code, {"__name__": "__docs__"})


@contextlib.contextmanager
def _inside(folder: Path) -> Iterator[None]:
    previous = Path.cwd()
    os.chdir(folder)
    try:
        yield
    finally:
        os.chdir(previous)


@contextlib.contextmanager
def _environ(**values: str) -> Iterator[None]:
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


@pytest.fixture(scope="module")
def workspace(tmp_path_factory: pytest.TempPathFactory) -> Workspace:
    return Workspace(tmp_path_factory.mktemp("docs"))


RUN_PAGES = sorted({b.page for b in ALL_BLOCKS if b.kind in ("run", "setup")})
SLOW_PAGES = sorted({b.page for b in ALL_BLOCKS if b.kind == "slow"})


def test_the_docs_have_commands_to_run() -> None:
    assert {"README.md", "docs/getting-started.md"} <= set(RUN_PAGES)
    assert "docs/real-data.md" in SLOW_PAGES


@pytest.mark.parametrize("page", RUN_PAGES)
def test_commands_of(page: str, workspace: Workspace) -> None:
    workspace.run_page(page)


@pytest.mark.slow
@pytest.mark.parametrize("page", SLOW_PAGES)
def test_slow_commands_of(page: str, workspace: Workspace) -> None:
    folder = data_dir()
    for name, where in DATA_FILES.items():
        source = folder / where if folder else None
        if source is None or not source.is_file():
            pytest.skip(f"real dataset not found: set CUIKSLAM_DATA to the folder holding {where}")
        link = workspace.folder / name
        if not link.exists():
            link.symlink_to(source)
    workspace.run_page(page, kinds=("slow",))


def test_outputs_are_read_from_the_options() -> None:
    assert outputs(["solve", "a.jsonl", "--json", "r.json", "--csv", "r.csv"]) == [
        "r.json",
        "r.csv",
    ]
    assert outputs(["paper"]) == ["cuikslam-paper.png"]
    assert outputs(["paper", "--figure", "p.png"]) == ["p.png"]


# ------------------------------------------------------------------ the README's promises
def test_readme_is_a_landing_page() -> None:
    lines = README.read_text(encoding="utf-8").splitlines()
    assert len(lines) <= 250, len(lines)
    first_screen = " ".join(" ".join(lines[:25]).split())
    assert "envelope" in first_screen and "whatever the correspondence" in first_screen


def test_readme_has_two_setup_commands_and_ci_runs_the_second() -> None:
    setup = [b for b in ALL_BLOCKS if b.kind == "setup"]
    assert [b.page for b in setup] == ["README.md", "README.md"]
    install, tests = (b.text.strip() for b in setup)
    assert install.startswith("pip install . && cuikslam paper"), install
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert tests in ci, f"{tests!r} is not a line of .ci/run"


def test_readme_links_point_at_files() -> None:
    text = README.read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text)
    local = [t for t in targets if "://" not in t]
    assert "docs/getting-started.md" in local
    missing = [t for t in local if not (ROOT / t).is_file()]
    assert not missing, missing


# ------------------------------------------------------------------ the architecture page
def _resolves(name: str) -> bool:
    """Whether ``a.b.c`` names a module, or an attribute of one (a class, a function)."""
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            value = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            if not hasattr(value, attribute):
                return False
            value = getattr(value, attribute)
        return True
    return False


def test_architecture_page_names_only_what_exists() -> None:
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    names = set(re.findall(r"`(cuikslam(?:\.\w+)+)`", text))
    assert len(names) > 30
    missing = sorted(n for n in names if not _resolves(n))
    assert not missing, missing


def test_resolves_tells_a_missing_name() -> None:
    assert _resolves("cuikslam.solver.solve") and _resolves("cuikslam.cli.main")
    assert not _resolves("cuikslam.solver.no_such_function")
    assert not _resolves("cuikslam.no_such_module.solve")
