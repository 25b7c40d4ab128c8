"""tc.init: idempotent with the same arguments, and the arch/precision it reports."""

import numpy as np

import tai_coll as tc
from tai_coll import runtime

from conftest import TEST_ARCH


def test_init_twice_with_same_arguments_is_harmless():
    first = runtime.info()
    scene = tc.Scene()
    scene.add_particles(positions=[[0.0, 1.0, 0.0]])
    again = tc.init(arch=first.requested_arch, precision="f64", threads=first.threads, seed=0)
    assert again is first
    scene.step()  # the scene built before the second call still runs
    assert scene.time > 0


def test_session_runs_on_the_test_arch_in_f64():
    info = runtime.info()
    assert info.arch == TEST_ARCH and info.precision == "f64"
    assert info.threads == (2 if TEST_ARCH == "cpu" else None)
    assert runtime.float_dtype() is np.float64
    # f64 really reaches the kernels: a distance that f32 would round.
    x = 1.0 + 1e-12
    phi = tc.Plane(point=(0.0, 1.0, 0.0), normal=(0.0, 1.0, 0.0)).signed_distance([[0.0, x, 0.0]])
    assert abs(phi[0] - 1e-12) < 1e-15


def test_cpu_kernels_compile_without_taichis_cfg_optimisation():
    # runtime._start: on the CPU Taichi's CFG passes are off unless TI_CFG_OPTIMIZATION says
    # otherwise (they cost most of the largest kernels' compile time, and LLVM optimises
    # anyway); every test on the CPU compiles this way
    import os

    from taichi.lang import impl

    setting = os.environ.get("TI_CFG_OPTIMIZATION")
    expected = bool(int(setting)) if setting else TEST_ARCH != "cpu"
    assert impl.current_cfg().cfg_optimization is expected


def test_stale_generation_is_refused():
    import pytest

    with pytest.raises(RuntimeError, match="restarted Taichi"):
        runtime.check_generation(runtime.info().generation - 1, "this Scene")
