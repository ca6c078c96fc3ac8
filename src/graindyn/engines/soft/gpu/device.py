"""The CPU physics, recompiled for the GPU from the same Python source.

``device_function(f)`` turns a graindyn numba dispatcher (``scalar``, ``inlined``,
``kernel``) into a ``numba.cuda.jit(device=True)`` function built from its unchanged
``py_func``: the copy's globals map every dispatcher it names to its own device twin,
recursively and once each, and share everything else (math, module constants).  The
same twins serve the CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``), where compiled CPU
code cannot take the simulator's arrays, and a real GPU.  numba.cuda is imported only
here and only when called, so importing graindyn never needs it.
"""
from ...._jit import retarget

_TWINS = {}


def device_function(dispatcher):
    """The cuda device twin of a CPU dispatcher (memoized)."""
    from numba import cuda

    return retarget(dispatcher, cuda.jit(device=True), _TWINS)
