"""Start-up: a command loads only what it uses (each check in a fresh interpreter)."""

from __future__ import annotations

import subprocess
import sys

import pytest

HEAVY = ("rich", "numba", "scipy", "highspy", "matplotlib")


def loaded_after(code: str) -> list[str]:
    """The heavy top-level packages loaded once ``code`` ran in a fresh interpreter."""
    probe = f"{code}\nimport sys\nprint('LOADED', *(m for m in {HEAVY!r} if m in sys.modules))"
    done = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=300, check=True
    )
    return done.stdout.splitlines()[-1].split()[1:]


def test_help_loads_no_heavy_package() -> None:
    code = (
        "from cuikslam.cli.main import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit:\n    pass"
    )
    assert loaded_after(code) == []


def test_reading_a_log_loads_no_heavy_package(tmp_path) -> None:
    log = tmp_path / "log.jsonl"
    log.write_text(
        '{"type": "prior", "pose": 0, "x": [0, 0], "y": [0, 0], "theta": [0, 0]}\n',
        encoding="utf-8",
    )
    code = f"from cuikslam.log import read_log_file\nread_log_file({str(log)!r})"
    assert loaded_after(code) == []


def test_interval_array_operations_are_compiled_on_first_use() -> None:
    code = (
        "import numpy as np\n"
        "from cuikslam.interval import ops\n"
        "from cuikslam import interval as ia\n"
        "assert 'add' not in vars(ops) and 'mul' not in vars(ops)\n"
        "x = np.array([1.0, 2.0])\n"
        "assert ia.add(x, x).tolist() == [2.0, 4.0]\n"
        "assert 'add' in vars(ops) and 'mul' not in vars(ops)\n"
        "from cuikslam.interval import mul\n"
        "assert mul is ops.mul and 'mul' in dir(ia)\n"
    )
    loaded_after(code)  # raises on a failed assertion
    with pytest.raises(AttributeError):
        import cuikslam.interval as ia

        ia.no_such_operation  # noqa: B018


def test_known_correspondence_warm_up_leaves_the_search_kernels_alone() -> None:
    code = (
        "from cuikslam.solver import warm_up\n"
        "from cuikslam.hypotheses import _kernels\n"
        "warm_up(False)\n"
        "assert not _kernels.apply.signatures, _kernels.apply.signatures\n"
        "assert warm_up(False) == 0.0\n"
        "warm_up(True)\n"
        "assert _kernels.apply.signatures\n"
    )
    loaded_after(code)


def test_the_main_names_are_importable_from_the_package_without_loading_them() -> None:
    code = (
        "import cuikslam\n"
        "assert {'solve', 'SolveOptions', 'read_log_file', 'Solution'} <= set(cuikslam.__all__)\n"
        "assert 'solve' in dir(cuikslam)\n"
    )
    assert loaded_after(code) == []
    import cuikslam

    for name in cuikslam.__all__:
        assert getattr(cuikslam, name) is not None, name
    with pytest.raises(AttributeError):
        cuikslam.no_such_name  # noqa: B018


def test_every_file_reader_has_its_writer_at_the_top_level() -> None:
    import cuikslam

    readers = {n for n in cuikslam.__all__ if n.startswith("read_") and n.endswith("_file")}
    assert "read_truth_file" in readers
    for name in readers:
        assert name.replace("read_", "write_", 1) in cuikslam.__all__, name


def test_warm_up_command_loads_every_kernel_a_paper_solve_uses() -> None:
    code = (
        "from cuikslam.cli.main import main\n"
        "assert main(['warm-up', '--jobs', '1']) == 0\n"
        "from cuikslam.hypotheses import _kernels\n"
        "from cuikslam.interval import ops\n"
        "from cuikslam.narrowing._propagate import propagate_arrays\n"
        "assert _kernels.apply.signatures and propagate_arrays.signatures\n"
        "assert {'sqrt', 'angle_of', 'cos', 'mul'} <= set(vars(ops))\n"
        "import importlib.util, os, cuikslam.solver\n"
        "assert os.path.exists(importlib.util.cache_from_source(cuikslam.solver.__file__))\n"
    )
    assert "numba" in loaded_after(code)  # raises when an assertion in the probe fails


def test_warm_up_command_rejects_zero_jobs(capsys) -> None:
    from cuikslam.cli.main import main

    with pytest.raises(SystemExit) as exit_info:
        main(["warm-up", "--jobs", "0"])
    assert exit_info.value.code == 2
    assert "--jobs: must be at least 1" in capsys.readouterr().err


def test_a_run_that_compiled_the_kernels_says_so_on_stderr(capsys) -> None:
    from cuikslam.cli.warm_up import COMPILE_NOTE_S, note_compiling

    note_compiling({"warm_up_s": COMPILE_NOTE_S + 1.0})
    out, err = capsys.readouterr()
    assert out == "" and "compiled the kernels" in err and "cuikslam warm-up" in err
    note_compiling({"warm_up_s": COMPILE_NOTE_S / 10})
    note_compiling({})
    assert capsys.readouterr() == ("", "")
