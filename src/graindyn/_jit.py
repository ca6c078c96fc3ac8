"""Numba compilation policy: the one place where jit flags live.

Every compiled function in graindyn is decorated with one of these at module level.
``scalar`` is for the pure physics functions (floats in, floats out) that the GPU
backend reuses unchanged, inlined at numba's IR level (array arguments then cost no
reference counting); ``inlined`` for a large one called from several parallel loops:
compiled once and inlined by LLVM (IR-inlining it into each parfor body multiplied the
compile time by three; LLVM inlining keeps all but about 3 % of the speed);
``kernel`` for serial array loops; ``parallel`` for loops over grains or contacts with
``prange``; ``driver`` for the time loop and what it calls every step, compiled without
reference counting (each call counted every array of the bundles it was passed in and
out: 2.3 us per step, engines/soft/loop.py): a driver and all it calls must allocate nothing,
as numba compiles them all without it; ``block`` for the serial body of one block of
a parallel loop (no reference counting), ``block_body`` for such a body LLVM-inlined into a block that calls it with
constant arguments, so that the branches they decide fold away (or into several
callers, compiled once); every call passes typed arguments (``np.int64(0)``,
``np.bool_(True)``), as a literal would compile the callee once more; ``callback`` for C
callbacks.  All are cached on disk (``cache=True``), so
importing graindyn compiles nothing and a warm start only loads the cache.
``error_model="numpy"`` makes division by zero give inf/nan as on the GPU instead of
raising, and fastmath stays off so that results are reproducible across machines.

Numba checks a cached kernel only against its own source file, not against the
functions it inlines from other files, so the cache lives in a folder named by a hash
of the engine source: any edit starts a fresh cache and nothing stale is ever loaded.
The hash covers physics/, core/, engines/ (the kernels and every constant they read) and any
other module that imports this one; pure-Python layers (config, output, CLI, run
driver) are left out, so editing them keeps the cache.
The folder's name also carries numba's threading layer (chosen in _threads, imported
first so that the layer is set before anything parallel is compiled).
``GRAINDYN_CACHE_DIR`` moves the root (default ~/.cache/graindyn).
"""
import hashlib
import os
import pathlib
import types

import numba
from numba.core.dispatcher import Dispatcher

from . import _threads

_SOURCE = pathlib.Path(__file__).parent
ENGINE = ("physics", "core", "engines", "_jit.py")


def source_digest():
    """Hash of every .py file of the package that may hold or feed compiled code."""
    h = hashlib.sha1()
    for path in sorted(_SOURCE.rglob("*.py")):
        text = path.read_bytes()
        if path.relative_to(_SOURCE).parts[0] not in ENGINE and b"_jit import" not in text:
            continue
        h.update(str(path.relative_to(_SOURCE)).encode())
        h.update(text)
    return h.hexdigest()[:16]


CACHE_ROOT = pathlib.Path(os.environ.get("GRAINDYN_CACHE_DIR",
                                         pathlib.Path.home() / ".cache" / "graindyn"))
CACHE_DIR = CACHE_ROOT / f"{source_digest()}-{_threads.LAYER}"
numba.config.CACHE_DIR = str(CACHE_DIR)



def cache_folders():
    """The compile-cache folders under CACHE_ROOT: [(path, bytes, current)], the one in
    use first.  Every edit of the engine source or change of threading layer starts a
    new folder and leaves the old ones behind."""
    if not CACHE_ROOT.is_dir():
        return []
    folders = [(path, sum(f.stat().st_size for f in path.rglob("*") if f.is_file()),
                path == CACHE_DIR) for path in CACHE_ROOT.iterdir() if path.is_dir()]
    return sorted(folders, key=lambda row: (not row[2], row[0].name))


def clear_cache(everything=False):
    """Remove the compile-cache folders other than the one in use (all of them with
    ``everything``: the next run compiles again); returns [(path, bytes)] removed."""
    import shutil

    removed = []
    for path, size, current in cache_folders():
        if everything or not current:
            shutil.rmtree(path, ignore_errors=True)
            removed.append((path, size))
    return removed


scalar = numba.njit(cache=True, error_model="numpy", inline="always")
inlined = numba.njit(cache=True, error_model="numpy", forceinline=True)
kernel = numba.njit(cache=True, error_model="numpy")
block = numba.njit(cache=True, error_model="numpy", _nrt=False)
block_body = numba.njit(cache=True, error_model="numpy", forceinline=True, _nrt=False)
parallel = numba.njit(cache=True, error_model="numpy", parallel=True)
driver = numba.njit(cache=True, error_model="numpy", _nrt=False)
prange = numba.prange


def callback(signature):
    """A C callback of the given numba signature, cached on disk (the CPU's law loops,
    engines/soft/law_loop.py, called from compiled code through their address)."""
    return numba.cfunc(signature, cache=True, error_model="numpy")


def retarget(dispatcher, make, memo, swap=None, suffix=""):
    """A copy of a graindyn dispatcher compiled by ``make`` from its unchanged
    ``py_func``: the copy's globals map every dispatcher it names to its own copy
    (recursively, once each, in ``memo``) and the names in ``swap`` to their
    replacements; everything else (math, module constants) is shared.  ``suffix`` is
    added to the qualified names (the disk cache keys on them).  The GPU backend
    builds its device functions this way (engines/soft/gpu/device.py), the CPU's vectorized law
    loop its workspace laws (engines/soft/law_loop.py)."""
    twin = memo.get(dispatcher)
    if twin is not None:
        return twin
    swap = swap or {}
    source = dispatcher.py_func
    names = dict(source.__globals__)
    for name in source.__code__.co_names:          # only the globals it reads
        if name in swap:
            names[name] = swap[name]
        elif isinstance(names.get(name), Dispatcher):
            names[name] = retarget(names[name], make, memo, swap, suffix)
    clone = types.FunctionType(source.__code__, names, source.__name__, source.__defaults__,
                               source.__closure__)
    clone.__kwdefaults__ = source.__kwdefaults__
    clone.__qualname__ = source.__qualname__ + suffix
    clone.__module__ = source.__module__
    twin = memo[dispatcher] = make(clone)
    return twin
