"""MkDocs hooks of cuikslam's documentation (``mkdocs.yml``: ``hooks``).

* ``<!-- cuikslam-help solve -->`` in a page becomes the ``--help`` text of that command
  (``cuikslam solve --help``), taken from the parser of this checkout, so the command-line
  reference cannot drift from the code.
* Docstrings are written for numpydoc with Sphinx roles (``:func:`solve```); in the API
  pages a role is shown as the code it names (``solve``), without the role's name.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HELP_MARK = re.compile(r"^<!-- cuikslam-help ([a-z -]*?) -->$", re.MULTILINE)
ROLE = re.compile(
    r":(?:py:)?(?:func|class|mod|meth|attr|data|obj|exc|const):<code>(~?)([^<]*)</code>"
)
HELP_WIDTH = "88"


def _parser() -> argparse.ArgumentParser:
    """The ``cuikslam`` parser of this checkout (not of whatever cuikslam is installed)."""
    source = str(ROOT / "src")
    if source not in sys.path:
        sys.path.insert(0, source)
    from cuikslam.cli.main import build_parser

    return build_parser()


def command_help(words: list[str]) -> str:
    """The help text of ``cuikslam WORDS... --help``, at a fixed width."""
    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = HELP_WIDTH
    try:
        parser = _parser()
        for word in words:
            (sub,) = (a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
            if word not in sub.choices:
                raise KeyError(f"no command 'cuikslam {' '.join(words)}'")
            parser = sub.choices[word]
        return parser.format_help()
    finally:
        if previous is None:
            os.environ.pop("COLUMNS", None)
        else:
            os.environ["COLUMNS"] = previous


def on_page_markdown(markdown: str, **kwargs) -> str:
    def help_block(match: re.Match[str]) -> str:
        return "```text\n" + command_help(match.group(1).split()).rstrip() + "\n```"

    return HELP_MARK.sub(help_block, markdown)


def on_page_content(html: str, **kwargs) -> str:
    def code(match: re.Match[str]) -> str:
        short, target = match.groups()
        return f"<code>{target.rsplit('.', 1)[-1] if short else target}</code>"

    return ROLE.sub(code, html)
