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


_EARLY = []          # the modules whose jobs started at collection


@pytest.fixture
def quiet_machine():
    """Wait for every job started at collection (pytest_collection_modifyitems): for
    tests that time the machine's cores."""
    for module in _EARLY:
        module.wait_early()


def pytest_collection_modifyitems(config, items):
    """Test modules with a ``start_early()`` (slow jobs in subprocesses: the CUDA
    simulator's) have it called once collection is done, and their tests run last: the
    jobs run at low priority beside the single-threaded suite, on the core it leaves
    idle, and are done or nearly when their tests ask for them."""
    early = [item for item in items if hasattr(getattr(item, "module", None), "start_early")]
    if not early:
        return
    for module in {item.module for item in early}:
        module.start_early()
        _EARLY.append(module)
    chosen = set(map(id, early))
    items[:] = [item for item in items if id(item) not in chosen] + early
