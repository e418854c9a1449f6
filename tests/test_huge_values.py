"""Valid logs with values near the largest double solve without a word from NumPy on
stderr (an adversarial tester's logs: widths past 1.8e308 overflowed sums of widths)."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from cuikslam.cli.main import main

DATA = Path(__file__).parent / "data" / "adversary"


@pytest.mark.parametrize("name", ["huge-offsets.jsonl", "huge-values-lp.jsonl"])
def test_values_near_the_largest_double_raise_no_warning(
    name: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    out = tmp_path / "r.json"
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert main(["solve", str(DATA / name), "--json", str(out), "-q"]) == 0
    assert "Warning" not in capsys.readouterr().err
    assert json.loads(out.read_text())["hypotheses"]
