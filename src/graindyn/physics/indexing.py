"""How the laws index a contact's history and the pair table:
``history[hrow(k, c)]`` is value c of contact k, ``params[prow(a, b, col)]`` column col
of the material pair (a, b).  In the engine's arrays (contacts x values, materials x
materials x columns) they are plain tuples.  The CPU's vectorized law loop
(engines/soft/law_loop.py) compiles the same laws with versions that point into the rows of
its workspace, where one contact's values sit a fixed stride apart, so that the
compiler can evaluate several contacts in SIMD lanes."""
from .._jit import scalar


@scalar
def hrow(k, c):
    """Index of value c of contact k in a (contacts, values) history array."""
    return k, c


@scalar
def prow(a, b, col):
    """Index of column col of the material pair (a, b) in the pair table."""
    return a, b, col
