"""Library messages name options as the Python API does; the command line names flags."""

from __future__ import annotations

import ast
import pickle
import re
from pathlib import Path

import cuikslam
from cuikslam.cli._messages import WORDING, worded
from cuikslam.messages import Message

SRC = Path(cuikslam.__file__).parent
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z-]*[a-z]")


def _message_strings(path: Path) -> list[tuple[int, str]]:
    """The string constants of ``path`` that are not docstrings (of modules, classes,
    functions and attributes: string statements), with their lines."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    docstrings = {
        id(node.value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
    }
    strings = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str):
            if id(node) not in docstrings:
                strings.append((node.lineno, node.value))
    return strings


def test_no_library_message_names_a_command_line_flag() -> None:
    found = []
    for path in sorted(SRC.rglob("*.py")):
        where = path.relative_to(SRC).as_posix()
        if where.startswith("cli/"):
            continue
        found += [f"{where}:{line}: {text!r}" for line, text in _message_strings(path)
                  if FLAG.search(text)]  # fmt: skip
    assert found == []


def test_every_code_the_library_uses_has_the_command_lines_wording() -> None:
    codes = set()
    for path in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (
                isinstance(node, ast.Call)
                and isinstance(node.func, ast.Name)
                and node.func.id == "Message"
                and node.args
                and isinstance(node.args[0], ast.Constant)
            ):
                codes.add(node.args[0].value)
    assert {"time_bound", "unreported_survivors", "strengthen_limit"} <= codes
    assert {"survivors_beyond_report", "reported_survivors_refuted"} <= codes
    assert codes <= set(WORDING)


def test_a_message_is_a_string_that_keeps_its_code_and_data() -> None:
    message = Message("unreported_survivors", "7 survivors ...; raise max_hypotheses", survivors=7)
    assert isinstance(message, str) and message.endswith("raise max_hypotheses")
    back = pickle.loads(pickle.dumps(message))
    assert (back, back.code, back.data) == (message, message.code, {"survivors": 7})
    assert worded(back) == "7 survivors were not kept for the report; raise --max-hypotheses"
    assert worded("no code") == "no code"


def test_the_command_line_words_an_input_error_with_its_flag(tmp_path: Path, capsys) -> None:
    """``cuikslam`` prints an InputFileError's problem in its own words."""
    from cuikslam.errors import InputFileError

    error = InputFileError("folder", None, Message("no_truth_at_start", "... move start", robot=2))
    assert str(error) == "folder: ... move start"
    assert worded(error.problem) == "no Vicon pose of robot 2 at the window start: move --start"
