"""Pure scalar contact physics: floats in, floats out, history updated in place.

The functions here are compiled with numba for the CPU and reused unchanged by the
GPU backend.  ``registry`` is the one table that names every law, its integer id,
its parameters (with units and bounds) and its history size.
"""
