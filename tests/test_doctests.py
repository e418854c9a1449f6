"""The examples in the library's docstrings run and print what they say."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import cuikslam


def _modules_with_examples() -> list[str]:
    names = []
    packages = [cuikslam.__name__] + [
        info.name for info in pkgutil.walk_packages(cuikslam.__path__, "cuikslam.")
    ]
    for name in packages:
        spec = importlib.util.find_spec(name)
        if spec is None or spec.origin is None or not spec.origin.endswith(".py"):
            continue
        with open(spec.origin, encoding="utf-8") as source:
            if ">>>" in source.read():
                names.append(name)
    return names


MODULES = _modules_with_examples()


def test_some_modules_have_examples() -> None:
    assert "cuikslam.interval.ops" in MODULES and "cuikslam.outcome.summary" in MODULES
    assert "cuikslam" in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0
    assert result.failed == 0
