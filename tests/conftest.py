"""Shared fixtures: small deterministic systems."""
import numba
import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture(scope="module")
def one_thread():
    """One numba thread for the module: tests of one or two grains then avoid prange
    barriers, which stall on a busy machine."""
    before = numba.get_num_threads()
    numba.set_num_threads(1)
    yield
    numba.set_num_threads(before)
