"""The CPU physics, recompiled for the GPU from the same Python source.

``device_function(f)`` turns a graindyn numba dispatcher (``scalar``, ``inlined``,
``kernel``) into a ``numba.cuda.jit(device=True)`` function built from its unchanged
``py_func``: the copy's globals map every dispatcher it names to its own device twin,
recursively and once each, and share everything else (math, module constants).  The
same twins serve the CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``), where compiled CPU
code cannot take the simulator's arrays, and a real GPU.  numba.cuda is imported only
here and only when called, so importing graindyn never needs it.
"""
import types

from numba.core.dispatcher import Dispatcher

_TWINS = {}


def device_function(dispatcher):
    """The cuda device twin of a CPU dispatcher (memoized)."""
    twin = _TWINS.get(dispatcher)
    if twin is not None:
        return twin
    from numba import cuda

    source = dispatcher.py_func
    names = dict(source.__globals__)
    for name in source.__code__.co_names:          # only the globals it reads
        value = names.get(name)
        if isinstance(value, Dispatcher):
            names[name] = device_function(value)
    clone = types.FunctionType(source.__code__, names, source.__name__, source.__defaults__,
                               source.__closure__)
    clone.__kwdefaults__ = source.__kwdefaults__
    clone.__qualname__ = source.__qualname__
    clone.__module__ = source.__module__
    twin = _TWINS[dispatcher] = cuda.jit(device=True)(clone)
    return twin
