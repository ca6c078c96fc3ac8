"""Numba compilation policy: the one place where jit flags live.

Every compiled function in graindyn is decorated with one of these at module level.
``scalar`` is for the pure physics functions (floats in, floats out) that the GPU
backend reuses unchanged; ``kernel`` for serial array loops; ``parallel`` for loops
over grains or contacts with ``prange``.  All are cached on disk (``cache=True``), so
importing graindyn compiles nothing and a warm start only loads the cache.
``error_model="numpy"`` makes division by zero give inf/nan as on the GPU instead of
raising, and fastmath stays off so that results are reproducible across machines.
"""
import numba

scalar = numba.njit(cache=True, error_model="numpy")
kernel = numba.njit(cache=True, error_model="numpy")
parallel = numba.njit(cache=True, error_model="numpy", parallel=True)
prange = numba.prange
