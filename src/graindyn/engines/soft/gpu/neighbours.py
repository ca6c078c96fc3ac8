"""Neighbour lists built on the device: the CPU's rebuild (core/neighbors.py)
as a sequence of kernels, with the CPU's own per-grain functions for the grid, the
cell of a grain, the pair scan, the wall scan and the history carry-over, for the
systems of an ensemble whose lists are due (a mask; engines/soft/gpu/layout.py says where each
system's grains, lists and walls sit; one system is the case K = 1).

1. wrap periodic coordinates and reduce each system's bounding box (per-row min/max
   in shared memory, folded per system), then one thread per system builds its grid
   with ``grid_from_extent``; each system's cells get their own slice of the cell
   arrays;
2. counting sort of the grains by cell: atomic counts, prefix sum, atomic placement,
   then each cell sorted by grain index, so the order is that of the CPU's stable sort;
3. per grain, count its partners j > i and its walls; one prefix sum over all systems,
   rebased per system onto its own slots, gives the CSR starts and the sizes needed,
   the numbers the host reads back;
4. if they fit: write the lists into the scratch arrays, carry each surviving pair's
   history over, copy the new lists of the due systems into the current arrays, and
   build their reverse lists (atomic counts, prefix sum, atomic placement, each segment
   sorted by pair index: the CPU's order again).
Integer atomics and sorts make every list identical to the CPU's, run after run.
"""
import math

import numpy as np
from numba import cuda, float64, int64

from ....core.neighbors import (carry_row, cell_id, grid_from_extent, scan_grain, wall_row,
                              wrap_coordinate)
from .. import loop
from .device import device_function
from .layout import ROW, row_grain
from .reductions import MAX, MIN, block_rows, fold, ops_array
from .reductions import kernels as reduction_kernels

_KERNELS = {}


def launch(kernel, n, *args):
    """Run ``kernel`` with one thread per item for n items, in blocks of at most ROW
    threads and no more threads than items."""
    threads = max(1, min(n, ROW))
    kernel[max(1, (n + threads - 1) // threads), threads](*args)


def kernels():
    """The list-building kernels (compiled on first use, once per process)."""
    if _KERNELS:
        return _KERNELS
    grid_fn = device_function(grid_from_extent)
    cell_fn = device_function(cell_id)
    scan_fn = device_function(scan_grain)
    carry_fn = device_function(carry_row)
    wall_fn = device_function(wall_row)
    wrap_fn = device_function(wrap_coordinate)

    @cuda.jit(device=True)
    def insertion_sort(values, first, last):
        """Sort values[first:last] in place (a few items)."""
        for a in range(first + 1, last):
            v = values[a]
            b = a - 1
            while b >= first and values[b] > v:
                values[b + 1] = values[b]
                b -= 1
            values[b + 1] = v

    @cuda.jit
    def extent(row_first, row_system, mask, positions, flag, lo, length, partial, bad, ops):
        """Wrap periodic coordinates; per-row min (partial[r, :3]) and max
        (partial[r, 3:]) of the positions (ops: MIN x 3, MAX x 3); bad[k] = 1 on a
        non-finite coordinate."""
        box = cuda.shared.array((ROW, 6), float64)
        t = cuda.threadIdx.x
        k, i, ok = row_grain(row_first, row_system, mask)
        for d in range(3):
            box[t, d] = math.inf
            box[t, 3 + d] = -math.inf
            if ok:
                x = positions[i, d]
                if flag[k, d]:
                    x = wrap_fn(x, lo[k, d], length[k, d])
                    positions[i, d] = x
                if not math.isfinite(x):
                    bad[k] = 1
                box[t, d] = x
                box[t, 3 + d] = x
        block_rows(box, 6, partial[cuda.blockIdx.x], ops)

    @cuda.jit
    def make_grid(box, n, cutoff, mask, flag, lo, length, origin, size, counts):
        """The grid over the box (low 3, high 3) of system k's grains (thread k)."""
        k = cuda.grid(1)
        if k < mask.size and mask[k] != 0:
            grid_fn(box[k, :3], box[k, 3:], n[k], cutoff[k], flag[k], lo[k], length[k],
                    origin[k], size[k], counts[k])

    @cuda.jit
    def zero(a):
        i = cuda.grid(1)
        if i < a.size:
            a[i] = 0

    @cuda.jit
    def bin_grains(row_first, row_system, mask, positions, origin, size, counts, cell_base,
                   cell, cell_start):
        """cell[i] (in its system's grid) and the count of grains per cell (in
        cell_start[cell_base[k] + c + 1])."""
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            c = cell_fn(positions[i, 0], positions[i, 1], positions[i, 2], origin[k], size[k],
                        counts[k])
            cell[i] = c
            cuda.atomic.add(cell_start, cell_base[k] + c + 1, 1)

    @cuda.jit
    def place(row_first, row_system, mask, cell, cell_base, cell_start, fill, items):
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            c = cell_base[k] + cell[i]
            items[cell_start[c] + cuda.atomic.add(fill, c, 1)] = i

    @cuda.jit
    def sort_cells(cell_start, values):
        """Each cell's grains in increasing index."""
        c = cuda.grid(1)
        if c < cell_start.size - 1:
            insertion_sort(values, cell_start[c], cell_start[c + 1])

    @cuda.jit
    def sort_rows(row_first, row_system, mask, start, values):
        """values[start[i + k]:start[i + k + 1]] sorted, for each grain i."""
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            insertion_sort(values, start[i + k], start[i + k + 1])

    @cuda.jit
    def scan_lists(row_first, row_system, mask, gb, clock, positions, radii, cell, counts,
                   cell_base, cell_start, items, flag, length, kind, geometry, offset, wb,
                   write, start, partners, wall_start, wall_ids):
        """Count (write False: into start[i + k + 1], wall_start[i + k + 1]) or write
        (at start[i + k]...) the partners j > i and the walls of each grain."""
        k, i, ok = row_grain(row_first, row_system, mask)
        if not ok:
            return
        skin = clock[k, loop.SKIN]
        first, last = wb[k], wb[k + 1]
        p = scan_fn(i, positions, radii, skin, cell, counts[k], cell_start[cell_base[k]:],
                    items, flag[k], length[k], write, partners, start[i + k])
        w = wall_fn(i, positions, radii, skin, kind[first:last], geometry[first:last],
                    offset[first:last], write, wall_ids, wall_start[i + k])
        if write:
            for q in range(wall_start[i + k], wall_start[i + k + 1]):
                wall_ids[q] += first
        else:
            start[i + k + 1] = p
            wall_start[i + k + 1] = w
            if i == gb[k]:
                start[i + k] = 0
                wall_start[i + k] = 0

    @cuda.jit
    def segments(gb, n, mask, summed, seg, need):
        """seg[k]: the inclusive prefix sum at system k's first entry; need[k]: its
        total (thread k)."""
        k = cuda.grid(1)
        if k < mask.size and mask[k] != 0:
            seg[k] = summed[gb[k] + k]
            need[k] = summed[gb[k] + k + n[k]] - seg[k]

    @cuda.jit
    def rebase(row_first, row_system, mask, gb, summed, seg, base, out):
        """out[e] = summed[e] - seg[k] + base[k] for system k's entries: a CSR start
        array on the system's own slots."""
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            out[i + k + 1] = summed[i + k + 1] - seg[k] + base[k]
            if i == gb[k]:
                out[i + k] = base[k]

    @cuda.jit
    def carry(row_first, row_system, mask, start, partners, history, new_start,
              new_partners, new_history):
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            carry_fn(i, start[k:], partners, history, new_start[k:], new_partners,
                     new_history)

    @cuda.jit
    def commit(row_first, row_system, mask, gb, new_start, new_items, new_history, start,
               items, history):
        """Grain i's new list, starts and histories copied into the current arrays."""
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            if i == gb[k]:
                start[i + k] = new_start[i + k]
            start[i + k + 1] = new_start[i + k + 1]
            for q in range(new_start[i + k], new_start[i + k + 1]):
                items[q] = new_items[q]
                for h in range(history.shape[1]):
                    history[q, h] = new_history[q, h]

    @cuda.jit
    def count_reverse(row_first, row_system, mask, start, partners, counts):
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            for q in range(start[i + k], start[i + k + 1]):
                cuda.atomic.add(counts, partners[q] + k + 1, 1)

    @cuda.jit
    def place_reverse(row_first, row_system, mask, start, partners, reverse_start, fill,
                      reverse_pairs):
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            for q in range(start[i + k], start[i + k + 1]):
                j = partners[q]
                reverse_pairs[reverse_start[j + k] + cuda.atomic.add(fill, j, 1)] = q

    @cuda.jit
    def set_reference(row_first, row_system, mask, positions, reference_positions):
        """Positions at this build (the half-skin rule's origin)."""
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            for d in range(3):
                reference_positions[i, d] = positions[i, d]

    @cuda.jit
    def set_wall_reference(wb, mask, offset, reference_offset):
        """Wall offsets of system k at this build (thread k)."""
        k = cuda.grid(1)
        if k < mask.size and mask[k] != 0:
            for w in range(wb[k], wb[k + 1]):
                for d in range(3):
                    reference_offset[w, d] = offset[w, d]

    @cuda.jit
    def block_scan(a, sums):
        """Inclusive prefix sum of each block (at most ROW threads) of a; the block
        totals go to sums."""
        tmp = cuda.shared.array(ROW, int64)
        t = cuda.threadIdx.x
        width = cuda.blockDim.x
        i = cuda.grid(1)
        tmp[t] = a[i] if i < a.size else 0
        cuda.syncthreads()
        step = 1
        while step < width:
            v = tmp[t - step] if t >= step else 0
            cuda.syncthreads()
            tmp[t] += v
            cuda.syncthreads()
            step *= 2
        if i < a.size:
            a[i] = tmp[t]
        if t == width - 1:
            sums[cuda.blockIdx.x] = tmp[t]

    @cuda.jit
    def add_offsets(a, sums):
        i = cuda.grid(1)
        b = cuda.blockIdx.x
        if b > 0 and i < a.size:
            a[i] += sums[b - 1]

    _KERNELS.update(locals())
    return _KERNELS


class DeviceNeighbours:
    """Scratch arrays and the host side of the device rebuild for the systems of a
    layout (engines/soft/gpu/layout.py)."""

    def __init__(self, layout):
        self.k = dict(kernels(), **reduction_kernels())
        self.layout = layout
        n, systems = int(layout.gb[-1]), layout.k
        self.n = n
        # grain and cell indices fit in int32 (below 2^31 grains); the cell arrays are
        # sized to the grids of the first build and grow when a later build needs more
        self.cell = cuda.device_array(n, np.int32)
        self.items = cuda.device_array(n, np.int32)
        self.cell_start = cuda.device_array(1, np.int32)
        self.fill = cuda.device_array(n, np.int32)
        self.partial = cuda.device_array((layout.rows, 6))
        self.box = cuda.device_array((systems, 6))                 # low (3), high (3)
        self.grid = [cuda.device_array((systems, 3)) for _ in range(2)]  # origin, size
        self.box_ops = ops_array([MIN] * 3 + [MAX] * 3)
        self.counts = cuda.device_array((systems, 3), np.int64)
        self.bad = cuda.device_array(systems, np.int64)
        self.seg = cuda.device_array(systems, np.int64)
        self.need = cuda.device_array((2, systems), np.int64)
        self.sizes = cuda.to_device(layout.n)
        self.cell_base = cuda.device_array(systems + 1, np.int64)
        self._sums = []          # one block-total buffer per level of the prefix sum

    def memory_bytes(self):
        """Bytes of the scratch arrays of the device build."""
        arrays = [self.cell, self.items, self.cell_start, self.fill, self.partial,
                  self.counts, self.bad, self.box, *self.grid, self.box_ops, self.seg,
                  self.need, self.sizes, self.cell_base, *self._sums]
        return sum(a.nbytes for a in arrays)

    def scan(self, a, level=0):
        """In-place inclusive prefix sum of the integer device array a (exact), in
        blocks of ROW items (one block of a.size threads when a is shorter)."""
        threads = max(1, min(a.size, ROW))
        blocks = (a.size + threads - 1) // threads
        if len(self._sums) == level:
            self._sums.append(cuda.device_array(0, np.int64))
        if self._sums[level].size < blocks:
            self._sums[level] = cuda.device_array(blocks, np.int64)
        sums = self._sums[level][:blocks]
        self.k["block_scan"][blocks, threads](a, sums)
        if blocks > 1:
            self.scan(sums, level + 1)
            self.k["add_offsets"][blocks, threads](a, sums)

    def _cells(self, due):
        """The cell-start table for the grids just built, each due system's cells after
        the last one's (one read of the cell counts): (total + 1,) int32, grown when the
        grids need more cells than any before."""
        cells = np.where(due != 0, np.prod(self.counts.copy_to_host(), axis=1), 0)
        base = np.concatenate(([0], np.cumsum(cells))).astype(np.int64)
        self.cell_base.copy_to_device(base)
        total = int(base[-1])
        if self.cell_start.size < total + 1:
            size = int(1.2 * total) + 2
            self.cell_start = cuda.device_array(size, np.int32)
            self.fill = cuda.device_array(max(size, self.n), np.int32)
        return self.cell_start[:total + 1]

    def _rows(self, kernel, mask, *args):
        """``kernel`` with one block per row of the layout (one thread per grain)."""
        lay = self.layout
        kernel[lay.rows, lay.threads](lay.dev["row_first"], lay.dev["row_system"], mask,
                                      *args)

    def _starts(self, mask, summed, base, out):
        """out: the CSR starts of the masked systems from the prefix sum ``summed`` of
        their counts, on the slots from ``base``; returns the totals (device)."""
        lay = self.layout
        launch(self.k["segments"], lay.k, lay.dev["gb"], self.sizes, mask, summed, self.seg,
                                     out[1])
        self._rows(self.k["rebase"], mask, lay.dev["gb"], summed, self.seg, base, out[0])

    def build(self, due, mask, grains, pairs, walls, periodic, clock, cutoff):
        """Rebuild the lists of the systems with due[k] != 0 (host array; ``mask`` its
        device copy); grains, pairs, walls and periodic are the engine's device bundles
        (layout.bundles: Grains, Pairs, WallBundle, PeriodicBox of device arrays; the new
        lists are built in their scratch arrays); clock (K, 12) and cutoff (K,) [m] are
        device arrays.  Returns (pairs needed (K,), wall
        contacts needed (K,), bad (K,)): when a system's coordinates are not finite
        (bad) or a list does not fit its slots, nothing but the wrapped positions has
        changed."""
        k, lay = self.k, self.layout
        positions, radii = grains.positions, grains.radii
        start, partners, reverse_start, reverse_pairs = \
            pairs.start, pairs.partners, pairs.reverse_start, pairs.reverse_pairs
        # the new lists are built in the scratch arrays, then committed
        new_start, new_partners = pairs.scratch_start, pairs.scratch_partners
        kind, geometry, offset = walls.kind, walls.geometry, walls.offset
        new_wall_start, new_wall_ids = walls.scratch_wall_start, walls.scratch_wall_ids
        flag, lo, length = periodic.flag, periodic.lo, periodic.length
        origin, size = self.grid
        dev = lay.dev
        launch(k["zero"], lay.k, self.bad)
        self._rows(k["extent"], mask, positions, flag, lo, length, self.partial, self.bad,
                   self.box_ops)
        fold(self.k, lay, self.partial, self.box_ops, self.box)
        launch(k["make_grid"], lay.k, self.box, self.sizes, cutoff, mask, flag, lo, length,
                                 origin, size, self.counts)
        bad = self.bad.copy_to_host() * due
        if bad.any():                               # no grid over non-finite positions
            return None, None, bad
        cell_start = self._cells(due)
        ncell = cell_start.size - 1
        launch(k["zero"], ncell + 1, cell_start)
        launch(k["zero"], ncell, self.fill)
        self._rows(k["bin_grains"], mask, positions, origin, size, self.counts,
                   self.cell_base, self.cell, cell_start)
        self.scan(cell_start)
        self._rows(k["place"], mask, self.cell, self.cell_base, cell_start, self.fill,
                   self.items)
        launch(k["sort_cells"], ncell, cell_start, self.items)
        scan_args = (dev["gb"], clock, positions, radii, self.cell, self.counts,
                     self.cell_base, cell_start, self.items, flag, length, kind, geometry,
                     offset, dev["wb"])
        self._rows(k["scan_lists"], mask, *scan_args, False, new_start, new_partners,
                   new_wall_start, new_wall_ids)
        self.scan(new_start)
        self.scan(new_wall_start)
        self._starts(mask, new_start, dev["pb"], (new_start, self.need[0]))
        self._starts(mask, new_wall_start, dev["cb"], (new_wall_start, self.need[1]))
        need = self.need.copy_to_host() * due
        capacity = np.diff(lay.pb), np.diff(lay.cb)
        if np.any(need[0] > capacity[0]) or np.any(need[1] > capacity[1]):
            return need[0], need[1], bad
        self._rows(k["scan_lists"], mask, *scan_args, True, new_start, new_partners,
                   new_wall_start, new_wall_ids)
        lists = (((pairs.start, pairs.partners, pairs.history),
                  (pairs.scratch_start, pairs.scratch_partners, pairs.scratch_history)),
                 ((walls.wall_start, walls.wall_ids, walls.wall_history),
                  (walls.scratch_wall_start, walls.scratch_wall_ids,
                   walls.scratch_wall_history)))
        for old, new in lists:          # (start, listed, history) of each list
            self._rows(k["carry"], mask, *old, *new)
            self._rows(k["commit"], mask, dev["gb"], *new, *old)
        # reverse lists: counted into the free scratch starts, then rebased
        counts = new_start
        launch(k["zero"], counts.size, counts)
        launch(k["zero"], self.n, self.fill)
        self._rows(k["count_reverse"], mask, start, partners, counts)
        self.scan(counts)
        self._starts(mask, counts, dev["pb"], (reverse_start, self.need[0]))
        self._rows(k["place_reverse"], mask, start, partners, reverse_start, self.fill,
                   reverse_pairs)
        self._rows(k["sort_rows"], mask, reverse_start, reverse_pairs)
        self._rows(k["set_reference"], mask, positions, grains.reference_positions)
        launch(k["set_wall_reference"], lay.k, dev["wb"], mask, offset,
               walls.reference_offset)
        return need[0], need[1], bad
