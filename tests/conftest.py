"""Taichi starts once per test session: CPU backend, f64, 2 threads, fixed seed."""

import pytest

import tai_coll as tc


def pytest_configure(config):
    tc.init(arch="cpu", precision="f64", threads=2, seed=0)


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)
