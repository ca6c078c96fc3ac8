"""Neighbour lists built on the device (issue 6): the CPU's rebuild (core/neighbors.py)
as a sequence of kernels, with the CPU's own per-grain functions for the grid, the
cell of a grain, the pair scan, the wall scan and the history carry-over.

1. wrap periodic coordinates and reduce the bounding box (per-block min/max in
   shared memory, then one thread builds the grid with ``grid_from_extent``);
2. counting sort of the grains by cell: atomic counts, prefix sum, atomic placement,
   then each cell sorted by grain index, so the order is that of the CPU's stable sort;
3. per grain, count its partners j > i and its walls; prefix sums give the CSR starts
   and the sizes needed, the one number the host reads back;
4. if they fit: write the lists into the scratch arrays, carry each surviving pair's
   history over, and build the reverse list (atomic counts, prefix sum, atomic
   placement, each segment sorted by pair index: the CPU's order again).
The new lists are in the scratch arrays; the caller swaps them with the current ones.
Integer atomics and sorts make every list identical to the CPU's, run after run.
"""
import math

import numpy as np
from numba import cuda, float64, int64

from ..core.neighbors import (carry_row, cell_id, grid_from_extent, scan_grain, wall_row,
                              wrap_coordinate)
from .device import device_function
from .reductions import MAX, MIN, fold, ops_array
from .reductions import kernels as reduction_kernels

THREADS = 128          # threads per block; a power of two (tree reductions)
_KERNELS = {}


def launch(kernel, n, *args):
    """Run ``kernel`` with one thread per item for n items."""
    kernel[max(1, (n + THREADS - 1) // THREADS), THREADS](*args)


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

    @cuda.jit
    def extent(positions, flag, lo, length, partial, bad):
        """Wrap periodic coordinates; per-block min (partial[b, :3]) and max
        (partial[b, 3:]) of the positions; bad[0] = 1 on a non-finite coordinate."""
        low = cuda.shared.array((THREADS, 3), float64)
        high = cuda.shared.array((THREADS, 3), float64)
        t = cuda.threadIdx.x
        i = cuda.grid(1)
        for d in range(3):
            if i < positions.shape[0]:
                x = positions[i, d]
                if flag[d]:
                    x = wrap_fn(x, lo[d], length[d])
                    positions[i, d] = x
                if not math.isfinite(x):
                    bad[0] = 1
                low[t, d] = x
                high[t, d] = x
            else:
                low[t, d] = math.inf
                high[t, d] = -math.inf
        cuda.syncthreads()
        s = THREADS // 2
        while s > 0:
            if t < s:
                for d in range(3):
                    low[t, d] = min(low[t, d], low[t + s, d])
                    high[t, d] = max(high[t, d], high[t + s, d])
            cuda.syncthreads()
            s //= 2
        if t == 0:
            for d in range(3):
                partial[cuda.blockIdx.x, d] = low[0, d]
                partial[cuda.blockIdx.x, 3 + d] = high[0, d]

    @cuda.jit
    def make_grid(box, n, cutoff, flag, lo, length, origin, size, counts):
        """The grid over the box (low 3, high 3) of the grains (one thread)."""
        if cuda.grid(1) == 0:
            grid_fn(box[:3], box[3:], n, cutoff, flag, lo, length, origin, size, counts)

    @cuda.jit
    def zero(a):
        i = cuda.grid(1)
        if i < a.size:
            a[i] = 0

    @cuda.jit
    def bin_grains(positions, origin, size, counts, cell, cell_start):
        """cell[i] and the count of grains per cell (in cell_start[c + 1])."""
        i = cuda.grid(1)
        if i < positions.shape[0]:
            c = cell_fn(positions[i, 0], positions[i, 1], positions[i, 2], origin, size,
                        counts)
            cell[i] = c
            cuda.atomic.add(cell_start, c + 1, 1)

    @cuda.jit
    def place(cell, cell_start, fill, items):
        i = cuda.grid(1)
        if i < cell.size:
            c = cell[i]
            items[cell_start[c] + cuda.atomic.add(fill, c, 1)] = i

    @cuda.jit
    def sort_segments(segment_start, values):
        """Insertion sort of each segment values[start[c]:start[c + 1]] (a few items)."""
        c = cuda.grid(1)
        if c < segment_start.size - 1:
            first = segment_start[c]
            for a in range(first + 1, segment_start[c + 1]):
                v = values[a]
                b = a - 1
                while b >= first and values[b] > v:
                    values[b + 1] = values[b]
                    b -= 1
                values[b + 1] = v

    @cuda.jit
    def count(positions, radii, skin, cell, counts, cell_start, items, flag, length, kind,
              geometry, offset, start, wall_start):
        """Partners j > i and walls of each grain, in start[i + 1], wall_start[i + 1]."""
        i = cuda.grid(1)
        if i < positions.shape[0]:
            start[i + 1] = scan_fn(i, positions, radii, skin, cell, counts, cell_start,
                                   items, flag, length, False, start, 0)
            wall_start[i + 1] = wall_fn(i, positions, radii, skin, kind, geometry, offset,
                                        False, wall_start, 0)
        if i == 0:
            start[0] = 0
            wall_start[0] = 0

    @cuda.jit
    def fill_lists(positions, radii, skin, cell, counts, cell_start, items, flag, length,
                   kind, geometry, offset, start, partners, wall_start, wall_ids):
        i = cuda.grid(1)
        if i < positions.shape[0]:
            scan_fn(i, positions, radii, skin, cell, counts, cell_start, items, flag, length,
                    True, partners, start[i])
            wall_fn(i, positions, radii, skin, kind, geometry, offset, True, wall_ids,
                    wall_start[i])

    @cuda.jit
    def carry(start, partners, history, new_start, new_partners, new_history):
        i = cuda.grid(1)
        if i < new_start.size - 1:
            carry_fn(i, start, partners, history, new_start, new_partners, new_history)

    @cuda.jit
    def count_reverse(start, partners, reverse_start):
        i = cuda.grid(1)
        if i < start.size - 1:
            for k in range(start[i], start[i + 1]):
                cuda.atomic.add(reverse_start, partners[k] + 1, 1)

    @cuda.jit
    def place_reverse(start, partners, reverse_start, fill, reverse_pairs):
        i = cuda.grid(1)
        if i < start.size - 1:
            for k in range(start[i], start[i + 1]):
                j = partners[k]
                reverse_pairs[reverse_start[j] + cuda.atomic.add(fill, j, 1)] = k

    @cuda.jit
    def set_reference(positions, reference_positions, offset, reference_offset):
        """Positions and wall offsets at this build (the half-skin rule's origin)."""
        i = cuda.grid(1)
        if i < positions.shape[0]:
            for d in range(3):
                reference_positions[i, d] = positions[i, d]
        if i < offset.shape[0]:
            for d in range(3):
                reference_offset[i, d] = offset[i, d]

    @cuda.jit
    def block_scan(a, sums):
        """Inclusive prefix sum of each block of a; the block totals go to sums."""
        tmp = cuda.shared.array(THREADS, int64)
        t = cuda.threadIdx.x
        i = cuda.grid(1)
        tmp[t] = a[i] if i < a.size else 0
        cuda.syncthreads()
        step = 1
        while step < THREADS:
            v = tmp[t - step] if t >= step else 0
            cuda.syncthreads()
            tmp[t] += v
            cuda.syncthreads()
            step *= 2
        if i < a.size:
            a[i] = tmp[t]
        if t == THREADS - 1:
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
    """Scratch arrays and the host side of the device rebuild for N grains."""

    def __init__(self, n):
        self.k = dict(kernels(), **reduction_kernels())
        self.n = n
        # grain and cell indices fit in int32 (below 2^31 grains); the cell arrays are
        # sized to the grid of the first build and grow when a later grid needs more
        self.cell = cuda.device_array(n, np.int32)
        self.items = cuda.device_array(n, np.int32)
        self.cell_start = cuda.device_array(1, np.int32)
        self.fill = cuda.device_array(n, np.int32)
        self.partial = cuda.device_array(((n + THREADS - 1) // THREADS, 6))
        self.box = cuda.device_array(6)                          # low (3), high (3)
        self.grid = [cuda.device_array(3) for _ in range(2)]     # origin, cell size
        self.box_ops = ops_array([MIN] * 3 + [MAX] * 3)
        self.counts = cuda.device_array(3, np.int64)
        self.bad = cuda.to_device(np.zeros(1, np.int64))
        self._sums = []          # one block-total buffer per level of the prefix sum

    def memory_bytes(self):
        """Bytes of the scratch arrays of the device build."""
        arrays = [self.cell, self.items, self.cell_start, self.fill, self.partial,
                  self.counts, self.bad, self.box, *self.grid, self.box_ops, *self._sums]
        return sum(a.nbytes for a in arrays)

    def scan(self, a, level=0):
        """In-place inclusive prefix sum of the integer device array a (exact)."""
        blocks = (a.size + THREADS - 1) // THREADS
        if len(self._sums) == level:
            self._sums.append(cuda.device_array(0, np.int64))
        if self._sums[level].size < blocks:
            self._sums[level] = cuda.device_array(blocks, np.int64)
        sums = self._sums[level][:blocks]
        self.k["block_scan"][blocks, THREADS](a, sums)
        if blocks > 1:
            self.scan(sums, level + 1)
            self.k["add_offsets"][blocks, THREADS](a, sums)

    def _cells(self):
        """The cell-start table for the grid just built: (ncell + 1,) int32, grown when
        the grid has more cells than any before (one read of the cell counts)."""
        ncell = int(np.prod(self.counts.copy_to_host()))
        if self.cell_start.size < ncell + 1:
            size = int(1.2 * ncell) + 2
            self.cell_start = cuda.device_array(size, np.int32)
            self.fill = cuda.device_array(max(size, self.n), np.int32)
        return self.cell_start[:ncell + 1]

    def build(self, cutoff, skin, grains, pairs, walls, periodic):
        """Rebuild into the scratch arrays of ``pairs`` and ``walls`` (device bundles in
        Simulation order).  Returns (pairs needed, wall contacts needed, finite): when a
        list does not fit, or a coordinate is not finite, nothing but the wrapped
        positions has changed."""
        k, n = self.k, self.n
        positions, radii = grains[0], grains[8]
        (start, partners, history, new_start, new_partners, new_history, reverse_start,
         reverse_pairs) = pairs[:8]
        kind, geometry, offset = walls[0], walls[1], walls[5]
        wall_start, wall_ids, wall_history, new_wall_start, new_wall_ids, new_wall_history \
            = walls[10:16]
        flag, lo, length = periodic
        origin, size = self.grid
        self.bad.copy_to_device(np.zeros(1, np.int64))
        launch(k["extent"], n, positions, flag, lo, length, self.partial, self.bad)
        fold(self.k, self.partial, self.box_ops, self.box)
        k["make_grid"][1, 1](self.box, n, cutoff, flag, lo, length, origin, size, self.counts)
        if self.bad.copy_to_host()[0] != 0:       # no grid over non-finite positions
            return 0, 0, False
        cell_start = self._cells()
        ncell = cell_start.size - 1
        launch(k["zero"], ncell + 1, cell_start)
        launch(k["zero"], ncell, self.fill)
        launch(k["bin_grains"], n, positions, origin, size, self.counts, self.cell,
               cell_start)
        self.scan(cell_start)
        launch(k["place"], n, self.cell, cell_start, self.fill, self.items)
        launch(k["sort_segments"], ncell, cell_start, self.items)
        scan_args = (positions, radii, skin, self.cell, self.counts, cell_start,
                     self.items, flag, length, kind, geometry, offset)
        launch(k["count"], n, *scan_args, new_start, new_wall_start)
        self.scan(new_start)
        self.scan(new_wall_start)
        needed = int(new_start[n:n + 1].copy_to_host()[0])
        wall_needed = int(new_wall_start[n:n + 1].copy_to_host()[0])
        if needed > partners.size or wall_needed > wall_ids.size:
            return needed, wall_needed, True
        launch(k["fill_lists"], n, *scan_args, new_start, new_partners, new_wall_start,
               new_wall_ids)
        launch(k["carry"], n, start, partners, history, new_start, new_partners, new_history)
        launch(k["carry"], n, wall_start, wall_ids, wall_history, new_wall_start, new_wall_ids,
               new_wall_history)
        launch(k["zero"], n + 1, reverse_start)
        launch(k["zero"], n, self.fill)
        launch(k["count_reverse"], n, new_start, new_partners, reverse_start)
        self.scan(reverse_start)
        launch(k["place_reverse"], n, new_start, new_partners, reverse_start, self.fill,
               reverse_pairs)
        launch(k["sort_segments"], n, reverse_start, reverse_pairs)
        launch(k["set_reference"], max(n, offset.shape[0]), positions, grains[13], offset,
               walls[9])
        return needed, wall_needed, True
