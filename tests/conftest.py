"""Taichi starts once per test session: f64, fixed seed, on the CPU backend with 2 threads.

TAI_COLL_TEST_ARCH=cuda (or another arch `tc.init` takes) runs the same suite on that
backend instead, for checking the kernels on a GPU; CI and the README's test command use
the CPU.
"""

import os

import pytest

import tai_coll as tc

TEST_ARCH = os.environ.get("TAI_COLL_TEST_ARCH", "cpu")


def pytest_configure(config):
    if TEST_ARCH == "cpu":
        tc.init(arch="cpu", precision="f64", threads=2, seed=0)
    else:
        info = tc.init(arch=TEST_ARCH, precision="f64", seed=0)
        if info.arch != TEST_ARCH:
            raise pytest.UsageError(f"TAI_COLL_TEST_ARCH={TEST_ARCH!r}, but Taichi started on {info.arch!r}")


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)
