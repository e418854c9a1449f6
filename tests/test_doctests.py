"""The examples in the library's docstrings run and print what they say."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import cuikslam


def _modules_with_examples() -> list[str]:
    names = []
    for info in pkgutil.walk_packages(cuikslam.__path__, "cuikslam."):
        spec = importlib.util.find_spec(info.name)
        if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
            continue
        with open(spec.origin, encoding="utf-8") as source:
            if ">>>" in source.read():
                names.append(info.name)
    return names


MODULES = _modules_with_examples()


def test_some_modules_have_examples() -> None:
    assert "cuikslam.interval.ops" in MODULES and "cuikslam.results.summary" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
