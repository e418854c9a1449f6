"""The kernel's rounding-mode guard: another library may switch the FPU away from nearest."""

from __future__ import annotations

import ctypes
import ctypes.util

import numpy as np
import pytest

from cuikslam import interval as ia
from cuikslam._fpu import ensure_round_to_nearest, rounds_to_nearest
from cuikslam.graph import KinematicGraph
from cuikslam.narrowing import Status, propagate

FE_UPWARD = 0x800  # x86-64 glibc
FE_DOWNWARD = 0x400
FE_TOWARDZERO = 0xC00

libm_name = ctypes.util.find_library("m")
pytestmark = pytest.mark.skipif(libm_name is None, reason="no C math library to change the mode")


def _set_mode(mode: int) -> None:
    ctypes.CDLL(libm_name).fesetround(mode)


@pytest.mark.parametrize("mode", [FE_UPWARD, FE_DOWNWARD, FE_TOWARDZERO])
def test_every_other_mode_is_detected_and_restored(mode: int) -> None:
    _set_mode(mode)
    assert not rounds_to_nearest()
    ensure_round_to_nearest()
    assert rounds_to_nearest()


@pytest.mark.parametrize("mode", [FE_UPWARD, FE_DOWNWARD, FE_TOWARDZERO])
def test_public_kernel_call_restores_the_mode(mode: int) -> None:
    _set_mode(mode)
    out = ia.add(np.array([0.1, 0.1]), np.array([0.2, 0.2]))
    assert rounds_to_nearest()
    assert out[0] < out[1]  # 0.1 + 0.2 is inexact: the enclosure has width
    assert out[0] == np.nextafter(0.1 + 0.2, -np.inf)


def test_propagation_restores_the_mode() -> None:
    graph = KinematicGraph()
    graph.add_pose_prior(0, (0.0, 0.0), (0.0, 0.0), (0.0, 0.0))
    graph.add_odometry(0, 1, (-0.01, 0.01), (0.99, 1.01))
    _set_mode(FE_UPWARD)
    result = propagate(graph)
    assert rounds_to_nearest()
    assert result.status is Status.CONSISTENT


def test_codac_changes_the_mode_and_cuikslam_restores_it() -> None:
    codac = pytest.importorskip("codac", reason="codac (test-only dependency) not installed")
    codac.CtcPolar().contract(
        codac.Interval(1, 2), codac.Interval(0, 3), codac.Interval(0, 10), codac.Interval(-4, 4)
    )
    ia.sqr(np.array([1.0, 2.0]))
    assert rounds_to_nearest()
