"""How K independent simulations sit in one set of device arrays (ensembles).

The single-system engine is the case K = 1.  System k's grains are rows gb[k]..gb[k+1]
of every per-grain array; its pair and wall-contact lists keep their own capacity, in
slots pb[k].. and cb[k].. of the per-contact arrays; its walls are wb[k]..wb[k+1].
A CSR start array holds n_k + 1 entries per system, so grain i of system k finds its
range at entries i + k and i + k + 1 (kernels pass ``start[k:]`` to the CPU's
per-grain functions, which then index it with the global i).  Stored indices are
global on the device (partners + gb[k], wall ids + wb[k], list starts + pb[k] or
cb[k]) and local on the host, so each Simulation keeps its own arrays, checkpoints
and protocols between chunks.

Reductions run over rows of at most ROW consecutive grains of one system (rows
rb[k]..rb[k+1] are system k's), so that every sum, maximum and tree is the one the
system gets when run alone: system k of an ensemble repeats it to the bit.
Materials keep their member's numbering: member k's pair table is params[table[k]],
each distinct table stored once.

The device keeps the arrays of the Simulation bundles (engines/soft/bundles.py), in the
groups "grains", "pairs", "walls", "periodic" and "loop", each a bundle of the same
class, and every table below names an array by (group, field).
"""
import numpy as np
from numba import cuda

from .. import loop
from ..bundles import WALL_TABLE_FIELDS, LoopArrays

ROW = 128              # most grains per row (and threads per block of per-grain kernels)

# (group, field) of the Simulation bundles -> the base added on the device
SHIFTS = {("pairs", "start"): "pb", ("pairs", "partners"): "gb",
          ("pairs", "reverse_start"): "pb", ("pairs", "reverse_pairs"): "pb",
          ("walls", "wall_start"): "cb", ("walls", "wall_ids"): "wb"}
# arrays allocated on the device but never transferred: rewritten before they are read
SCRATCH = {("pairs", "scratch_start"), ("pairs", "scratch_partners"),
           ("pairs", "scratch_history"), ("pairs", "own"), ("walls", "scratch_wall_start"),
           ("walls", "scratch_wall_ids"), ("walls", "scratch_wall_history")}
# one row per system (K, ...) rather than concatenated
STACKED = {("periodic", "flag"), ("periodic", "lo"), ("periodic", "length"),
           ("loop", "clock")}
# CSR starts: n_k + 1 entries per system
STARTS = {("pairs", "start"), ("pairs", "scratch_start"), ("pairs", "reverse_start"),
          ("walls", "wall_start"), ("walls", "scratch_wall_start")}
# one row per grain outside the "grains" group; ("loop", "integrator_history") is
# joined along its second axis (slots, N, 3)
PER_GRAIN = {("pairs", "own"), ("loop", "integrator_history")}
BY_GRAIN_AXIS = ("loop", "integrator_history")


def bundles(sim):
    """The host arrays of one Simulation by group, as bundles (engines/soft/bundles.py):
    grains (Grains), pairs (Pairs), walls (WallBundle), periodic (PeriodicBox) and loop
    (LoopArrays); the device copies keep the same groups and fields."""
    return {"grains": sim._grains(), "pairs": sim.pairs, "walls": sim._walls(),
            "periodic": sim._periodic(),
            "loop": LoopArrays(clock=sim.clock, integrator_history=sim.integrator_history)}


def _bases(sizes):
    return np.concatenate(([0], np.cumsum(sizes))).astype(np.int64)


class Layout:
    """The bases and rows of K simulations, and their arrays joined and split."""

    @staticmethod
    def check(sims):
        """ValueError unless the systems can share kernels: one contact model, one
        dimension, one integrator, at least one grain each."""
        first = sims[0]
        for s in sims[1:]:
            if not (np.array_equal(s.model_ids, first.model_ids)
                    and s.history_size == first.history_size):
                raise ValueError("the systems of a GPU ensemble need one contact model "
                                 f"({first.model} and {s.model} differ)")
            for what in (loop.DIM, loop.INTEGRATOR):
                if s.counters[what] != first.counters[what]:
                    raise ValueError("the systems of a GPU ensemble need one dimension and "
                                     "one integrator")
        if any(s.state.n < 1 for s in sims):
            raise ValueError("every system of an ensemble needs at least one grain")

    def __init__(self, sims):
        self.check(sims)
        self.sims = list(sims)
        self.k = len(sims)
        self.n = np.array([s.state.n for s in sims], np.int64)
        self.gb = _bases(self.n)
        self.wb = _bases([s.walls.kind.size for s in sims])
        rows = (self.n + ROW - 1) // ROW
        self.rb = _bases(rows)
        self.row_first = np.concatenate(
            [g + np.arange(r) * ROW for g, r in zip(self.gb[:-1], rows)] + [self.gb[-1:]])
        self.row_system = np.repeat(np.arange(self.k), rows)
        self.rows = int(self.rb[-1])
        self.max_rows = int(rows.max())
        self.threads = int(min(ROW, self.n.max()))
        self.refresh()

    def refresh(self):
        """The pair tables, the pair and wall-contact bases from the current host
        capacities, and every table the kernels read (``dev``: rb, row_first,
        row_system, gb, wb, pb, cb, table): called before each upload."""
        self._merge_params()
        self.pb = _bases([s.pairs.partners.size for s in self.sims])
        self.cb = _bases([s.wall_pairs.ids.size for s in self.sims])
        self.dev = {name: cuda.to_device(getattr(self, name)) for name in
                    ("rb", "row_first", "row_system", "gb", "wb", "pb", "cb", "table")}

    def _merge_params(self):
        """params (T, M, M, columns): each distinct pair table once (padded to the most
        materials M of any member); table[k] is member k's."""
        tables, index = [], []
        for s in self.sims:
            for t, table in enumerate(tables):
                if table.shape == s.params.shape and np.array_equal(table, s.params):
                    index.append(t)
                    break
            else:
                index.append(len(tables))
                tables.append(s.params)
        m = max(t.shape[0] for t in tables)
        self.params = np.zeros((len(tables), m, m, tables[0].shape[2]))
        for t, table in enumerate(tables):
            self.params[t, :table.shape[0], :table.shape[0]] = table
        self.table = np.array(index, np.int64)

    def join(self, group, name):
        """The device-layout (host) array of bundle field (group, name)."""
        arrays = [getattr(bundles(s)[group], name) for s in self.sims]
        if (group, name) in STACKED:
            return np.stack(arrays)
        shift = SHIFTS.get((group, name))
        if shift is not None:
            base = getattr(self, shift)
            arrays = [a + a.dtype.type(base[k]) for k, a in enumerate(arrays)]
        return np.concatenate(arrays, axis=1 if (group, name) == BY_GRAIN_AXIS else 0)

    def split(self, group, name, joined):
        """Write a joined array back into each system's host array."""
        for k, s in enumerate(self.sims):
            host = getattr(bundles(s)[group], name)
            if (group, name) in STACKED:
                host[...] = joined[k]
                continue
            lo, hi = self._range(group, name, k)
            part = joined[:, lo:hi] if (group, name) == BY_GRAIN_AXIS else joined[lo:hi]
            shift = SHIFTS.get((group, name))
            if shift is not None:
                part = part - part.dtype.type(getattr(self, shift)[k])
            host[...] = part

    def _range(self, group, name, k):
        """Rows of system k in the joined array of (group, name)."""
        if group == "grains" or (group, name) in PER_GRAIN:
            return self.gb[k], self.gb[k + 1]
        if (group, name) in STARTS:
            return self.gb[k] + k, self.gb[k + 1] + k + 1
        if group == "pairs":
            return self.pb[k], self.pb[k + 1]
        if name in WALL_TABLE_FIELDS:
            return self.wb[k], self.wb[k + 1]
        return self.cb[k], self.cb[k + 1]

    def shape(self, group, name):
        """Shape and dtype of the joined array (for arrays never transferred)."""
        a = getattr(bundles(self.sims[0])[group], name)
        rows = int(self._range(group, name, self.k - 1)[1])
        if (group, name) == BY_GRAIN_AXIS:
            return (a.shape[0], rows, *a.shape[2:]), a.dtype
        return (rows, *a.shape[1:]), a.dtype


@cuda.jit(device=True)
def row_grain(row_first, row_system, mask):
    """(system k, grain i, whether this thread has a grain of a masked-in system) for a
    kernel launched with one block per row of the layout."""
    b = cuda.blockIdx.x
    k = row_system[b]
    i = row_first[b] + cuda.threadIdx.x
    return k, i, mask[k] != 0 and i < row_first[b + 1]
