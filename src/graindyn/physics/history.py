"""How the laws index a contact's history: ``history[hrow(k, c)]`` is value c of
contact k.  In the engine's (contacts, values) arrays hrow is the pair (k, c); the
CPU's vectorized law loop (core/law_loop.py) compiles the same laws with an hrow that
points into the rows of its workspace, where one contact's values sit a fixed stride
apart and the compiler can evaluate several contacts in SIMD lanes."""
from .._jit import scalar


@scalar
def hrow(k, c):
    """Index of value c of contact k in a (contacts, values) history array."""
    return k, c
