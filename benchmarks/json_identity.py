"""JSON identity check: the result JSON, timings aside, before and after a change.

    python benchmarks/json_identity.py --save before/   # on the tree before the change
    python benchmarks/json_identity.py --check before/  # after it: exit status 1 on a difference

Solves, with default options (``cuikslam.solve(log)``: the ``"auto"`` work budget, no
wall-clock cap, so the result is the same on any machine and at any load), the seed's
experiment with landmark ids and without (the two logs ``cuikslam paper`` solves) and two
of the dense worlds of ``bench_hypotheses.py --dense`` (30 and 60 poses, seed 0). Each
result document (:func:`cuikslam.results.io.write_result_file`) is written with its
wall-clock fields removed: ``timings`` and ``statistics.worker_cpu_s`` (see
``docs/result-format.md``). ``--check`` compares each with the saved one, byte for byte,
and prints the keys that differ.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

WALL_CLOCK = (("timings",), ("statistics", "worker_cpu_s"))
"""Key paths of the result document that depend on the wall clock."""
DENSE_CASES = ((30, 0), (60, 0))
"""(poses, seed) of the dense worlds checked."""


def _cases() -> dict[str, Callable[[], Any]]:
    """Case name -> a function returning its log (built lazily: imports are slow)."""
    from bench_hypotheses import DENSE
    from cuikslam.simulate import simulate_paper, simulate_random_world

    cases: dict[str, Callable[[], Any]] = {
        "paper-known": lambda: simulate_paper(seed=0)[0],
        "paper-unknown": lambda: simulate_paper(seed=0, unknown=True)[0],
    }
    for n_poses, seed in DENSE_CASES:
        cases[f"dense-{n_poses}-s{seed}"] = (
            lambda n_poses=n_poses, seed=seed: simulate_random_world(
                seed=seed, n_poses=n_poses, n_landmarks=16, classes=("door", "corridor"),
                unknown=True, **DENSE,
            )[0]
        )  # fmt: skip
    return cases


def result_text(log: Any) -> str:
    """The result JSON of ``cuikslam.solve(log)``, its wall-clock fields removed."""
    from cuikslam import solve, write_result_file

    solution = solve(log)
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "result.json"
        write_result_file(solution, path)
        doc = json.loads(path.read_text())
    for keys in WALL_CLOCK:
        parent = doc
        for key in keys[:-1]:
            parent = parent.get(key, {})
        parent.pop(keys[-1], None)
    return json.dumps(doc, indent=1) + "\n"


def differences(old: Any, new: Any, where: str = "") -> Iterator[str]:
    """The key paths at which ``old`` and ``new`` differ (lists by index)."""
    if isinstance(old, dict) and isinstance(new, dict):
        if list(old) != list(new) and set(old) == set(new):
            yield f"{where or '.'}: key order"
        for key in old.keys() | new.keys():
            if key not in new:
                yield f"{where}.{key}: removed"
            elif key not in old:
                yield f"{where}.{key}: added"
            else:
                yield from differences(old[key], new[key], f"{where}.{key}")
    elif isinstance(old, list) and isinstance(new, list):
        if len(old) != len(new):
            yield f"{where}: length {len(old)} -> {len(new)}"
        for i, (a, b) in enumerate(zip(old, new, strict=False)):
            yield from differences(a, b, f"{where}[{i}]")
    elif old != new or type(old) is not type(new):
        yield f"{where}: {_short(old)} -> {_short(new)}"


def _short(value: Any) -> str:
    text = json.dumps(value)
    return text if len(text) <= 80 else text[:77] + "..."


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    mode = parser.add_mutually_exclusive_group(required=True)
    mode.add_argument("--save", type=Path, metavar="DIR", help="write the results to DIR")
    mode.add_argument("--check", type=Path, metavar="DIR", help="compare with the results in DIR")
    parser.add_argument("--cases", nargs="*", help="only these cases")
    args = parser.parse_args(argv)
    cases = _cases()
    if args.save:
        args.save.mkdir(parents=True, exist_ok=True)
    failed = 0
    for name, make_log in cases.items():
        if args.cases and name not in args.cases:
            continue
        start = time.perf_counter()
        text = result_text(make_log())
        seconds = time.perf_counter() - start
        path = (args.save or args.check) / f"{name}.json"
        if args.save:
            path.write_text(text)
            print(f"{name}: saved {path} ({seconds:.1f} s)")
            continue
        if not path.exists():
            print(f"{name}: no saved result {path}")
            failed += 1
            continue
        saved = path.read_text()
        if saved == text:
            print(f"{name}: identical ({seconds:.1f} s)")
            continue
        failed += 1
        found = list(differences(json.loads(saved), json.loads(text))) or ["formatting only"]
        print(f"{name}: DIFFERS in {len(found)} place(s) ({seconds:.1f} s)")
        for line in found[:40]:
            print(f"  {line}")
        if len(found) > 40:
            print(f"  ... {len(found) - 40} more")
    if args.check:
        print("identical" if not failed else f"{failed} case(s) differ")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
