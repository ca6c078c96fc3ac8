"""numba's threading layer and the thread count of a run, chosen on purpose.

graindyn's time loop enters two parallel regions per step (contact forces, then the
pass over grains), thousands of times per second for a small bed, so the fixed cost
of entering a region decides whether a second thread helps.  Measured on a 2-core AMD
EPYC with numba 0.68 (a ``prange(2)`` region of 400 multiply-adds, called in a compiled
loop; benchmarks/threading_layers.py):

- ``omp`` (GNU OpenMP): 1.8 us per region on 2 threads, steady.
- ``workqueue`` (numba's own): 65-140 us per region on 2 threads.
- ``tbb`` (oneTBB 2021.8, Debian's libtbb12): 9 us for the first 500 regions, then
  more with every call (138 us per region after 4 000 calls, 1.4 GB resident after
  about a million) on 2 threads; 1.0 us and steady on 1 thread.  numba's TBB pool
  (numba/np/ufunc/tbbpool.cpp) builds a new ``tbb::task_arena`` and a
  ``task_scheduler_observer`` for every region, and oneTBB keeps state behind for each
  of them (numba issue #10556, oneTBB issue #2056; a shared arena is proposed in numba
  PR #10560).  graindyn cannot fix numba's compiled pool, so it refuses TBB.

numba picks TBB by itself whenever libtbb.so.12 is found (conda, Intel toolchains,
Debian's yade and liggghts bring it).  So graindyn sets ``numba.config.THREADING_LAYER``
when ``_jit`` is imported, before anything parallel is compiled or launched: ``omp``
where numba's OpenMP pool loads, else ``workqueue``, with a one-line notice of its
cost; an explicit ``NUMBA_THREADING_LAYER=omp`` or ``workqueue`` is obeyed, ``tbb``
is refused with the reason.  If the host program launched numba's threads on TBB
before importing graindyn, the layer cannot change any more: runs then use one thread.

The automatic thread count (``run.threads = 0``) is one thread below ``CROSSOVER``
grains of the layer in use and every core from there on.  The crossovers are the
smallest benchmark beds on which two threads gained (BENCHMARKS.md, "Threading
layers"): on OpenMP the 280-grain bed ran 1.39 times slower on 2 threads and the
1 000-grain bed 1.14 times faster; on workqueue the 1 000-grain bed 3.1 times slower
and the 10 000-grain bed 1.15 times faster.
"""
import os
import sys

import numba
from numba.np.ufunc import parallel as _parallel

PREFERENCE = ("omp", "workqueue")
REFUSED = {"tbb": "numba's TBB pool slows down region after region (a new task arena per "
                  "parallel region: numba issue #10556)"}
COST = {"workqueue": "each parallel region costs about 100 us here against 2 us on OpenMP"}
# grains from which a second thread pays, per layer (one thread below)
CROSSOVER = {"omp": 1000, "workqueue": 10_000, "tbb": None}


def _loads(layer):
    """Whether numba's pool of ``layer`` loads on this machine."""
    try:
        if layer == "omp":
            from numba.np.ufunc import omppool  # noqa: F401
        else:
            from numba.np.ufunc import workqueue  # noqa: F401
    except ImportError:
        return False
    return True


def select():
    """Set numba's threading layer (once, before its threads start); returns (layer,
    notice), the notice None when the layer is OpenMP as asked or chosen."""
    if _parallel._is_initialized:
        layer = numba.threading_layer()
        if layer in REFUSED:
            return layer, (f"numba's threads already run on {layer}, which graindyn "
                           f"refuses on more than one thread: {REFUSED[layer]}; runs use "
                           "one thread")
        return layer, (f"numba's threads already run on {layer}: {COST[layer]}"
                       if layer in COST else None)
    asked = os.environ.get("NUMBA_THREADING_LAYER", "").strip().lower()
    notice = None
    if asked in PREFERENCE and _loads(asked):
        layer = asked
    else:
        layer = next((name for name in PREFERENCE if _loads(name)), "workqueue")
        if asked in REFUSED:
            notice = f"NUMBA_THREADING_LAYER={asked} refused: {REFUSED[asked]}"
        elif asked and asked != "default":
            notice = f"NUMBA_THREADING_LAYER={asked} not used"
    if layer in COST:
        why = "numba's OpenMP pool does not load here" if layer != asked else "as asked"
        notice = "; ".join(filter(None, [notice, f"threading layer {layer} ({why}): "
                                                 f"{COST[layer]}; small systems run on "
                                                 "one thread"]))
    elif notice:
        notice += f"; threading layer {layer}"
    numba.config.THREADING_LAYER = layer
    return layer, notice


LAYER, NOTICE = select()
if NOTICE:
    print(f"graindyn: {NOTICE}", file=sys.stderr)


def layer():
    """The threading layer in use: numba's own answer once its threads run, else the
    one graindyn set."""
    return numba.threading_layer() if _parallel._is_initialized else LAYER


def automatic(grains):
    """The thread count for ``grains`` grains: 1 below the layer's crossover, else every
    core numba offers."""
    crossover = CROSSOVER[layer()]
    if crossover is None or grains < crossover:
        return 1
    return numba.config.NUMBA_NUM_THREADS


def rule():
    """The automatic thread count in words, for the layer in use."""
    name = layer()
    crossover = CROSSOVER[name]
    if crossover is None:
        return f"one thread on {name}"
    return f"one thread below {crossover} grains on {name}, every core from there"


def use(requested, grains):
    """Set numba's thread count for a run of ``grains`` grains and return (threads,
    why): ``requested`` threads if > 0 (ValueError beyond the machine, or above one on
    a refused layer), else the automatic count."""
    name = layer()
    if requested:
        if requested > numba.config.NUMBA_NUM_THREADS:
            raise ValueError(f"run.threads = {requested}: this machine offers at most "
                             f"{numba.config.NUMBA_NUM_THREADS}")
        if requested > 1 and name in REFUSED:
            raise ValueError(f"run.threads = {requested}: the threading layer is {name}, "
                             f"refused on more than one thread: {REFUSED[name]}")
        threads, why = requested, "as asked"
    else:
        threads, why = automatic(grains), f"automatic for {grains} grains: {rule()}"
    numba.set_num_threads(threads)
    return threads, why
