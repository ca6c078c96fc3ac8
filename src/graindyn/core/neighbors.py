"""Neighbour search: cell lists feeding a half Verlet list with a skin, in CSR form.

A pair (i, j), i < j, is listed under i when |r_i - r_j| < R_i + R_j + skin, so the
list holds each pair once whatever the size ratio (cells are 2 R_max + skin wide).
The list is rebuilt only when the largest grain displacement since the last build,
plus the largest wall displacement, could exceed the skin (the half-skin rule).
Counting runs first; when the total exceeds the capacity the build stops before
writing anything and returns the size it needs, and the caller grows the arrays:
a neighbour is never dropped.  On rebuild each surviving pair keeps its contact
history.  Grain-wall candidates (distance below R_i + skin) are kept the same way.
All passes are O(N); counting and filling are parallel over grains, in fixed order.
"""
import math

import numpy as np

from .._jit import kernel, parallel, prange, scalar
from .walls import wall_distance


@scalar
def min_image(dx, periodic, length):
    """Minimum-image separation along an axis of period ``length`` (scalar arguments:
    arrays passed to a non-inlined function cost reference counting in hot loops)."""
    if periodic:
        dx -= length * math.floor(dx / length + 0.5)
    return dx


@kernel
def wrap_positions(positions, periodic_flag, periodic_lo, periodic_length):
    """Bring positions back into [lo, lo + L) along periodic axes."""
    for d in range(3):
        if periodic_flag[d]:
            lo = periodic_lo[d]
            length = periodic_length[d]
            for i in range(positions.shape[0]):
                positions[i, d] = lo + (positions[i, d] - lo) % length


@kernel
def _grid(positions, cutoff, periodic_flag, periodic_lo, periodic_length):
    """Cell grid: origin (3), cell size (3) and cell counts (3) of at least ``cutoff``."""
    n = positions.shape[0]
    lo = np.zeros(3)
    size = np.zeros(3)
    lengths = np.zeros(3)
    counts = np.ones(3, np.int64)
    for d in range(3):
        if periodic_flag[d]:
            lo[d] = periodic_lo[d]
            lengths[d] = periodic_length[d]
        else:
            a = positions[0, d]
            b = positions[0, d]
            for i in range(n):
                a = min(a, positions[i, d])
                b = max(b, positions[i, d])
            lo[d] = a
            lengths[d] = b - a
        # grains flung far apart by a blow-up: cap before converting to int (the
        # coarsening below brings the grid back to O(N) cells)
        counts[d] = max(1, int(min(lengths[d] / cutoff, 1e6)))
    # a dilute cloud spread far apart: coarsen so that the cells stay O(N)
    while counts[0] * counts[1] * counts[2] > 4 * n + 64:
        for d in range(3):
            counts[d] = max(1, counts[d] // 2)
    for d in range(3):
        size[d] = lengths[d] / counts[d] if periodic_flag[d] else max(lengths[d] / counts[d],
                                                                        cutoff)
    return lo, size, counts


@kernel
def _cell_of(x, d, lo, size, counts):
    c = int((x - lo[d]) / size[d])
    return min(max(c, 0), counts[d] - 1)


@kernel
def _cell_sort(positions, lo, size, counts):
    """Counting sort of grains by cell: (cell_start (C+1), cell_items (N), cell (N))."""
    n = positions.shape[0]
    ncell = counts[0] * counts[1] * counts[2]
    cell = np.empty(n, np.int64)
    start = np.zeros(ncell + 1, np.int64)
    for i in range(n):
        c = (_cell_of(positions[i, 0], 0, lo, size, counts) * counts[1]
             + _cell_of(positions[i, 1], 1, lo, size, counts)) * counts[2] \
            + _cell_of(positions[i, 2], 2, lo, size, counts)
        cell[i] = c
        start[c + 1] += 1
    for c in range(ncell):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    items = np.empty(n, np.int64)
    for i in range(n):
        items[fill[cell[i]]] = i
        fill[cell[i]] += 1
    return start, items, cell


@kernel
def _offsets(c, count, periodic):
    """Neighbouring cell indices along one axis, without duplicates."""
    out = np.empty(3, np.int64)
    k = 0
    if periodic:
        if count >= 3:
            for o in (-1, 0, 1):
                out[k] = (c + o) % count
                k += 1
        else:
            for o in range(count):
                out[k] = o
                k += 1
    else:
        for o in (-1, 0, 1):
            if 0 <= c + o < count:
                out[k] = c + o
                k += 1
    return out[:k]


@kernel
def _scan_grain(i, positions, radii, skin, cell, counts, cell_start, cell_items,
                periodic_flag, periodic_length, out, base):
    """Count (out is None-like: size 0) or write the partners j > i of grain i."""
    c = cell[i]
    cz = c % counts[2]
    cy = (c // counts[2]) % counts[1]
    cx = c // (counts[1] * counts[2])
    k = 0
    for ax in _offsets(cx, counts[0], periodic_flag[0]):
        for ay in _offsets(cy, counts[1], periodic_flag[1]):
            for az in _offsets(cz, counts[2], periodic_flag[2]):
                cc = (ax * counts[1] + ay) * counts[2] + az
                for s in range(cell_start[cc], cell_start[cc + 1]):
                    j = cell_items[s]
                    if j <= i:
                        continue
                    r2 = 0.0
                    for d in range(3):
                        dx = min_image(positions[i, d] - positions[j, d], periodic_flag[d],
                                       periodic_length[d])
                        r2 += dx * dx
                    cut = radii[i] + radii[j] + skin
                    if r2 < cut * cut:
                        if out.size > 0:
                            out[base + k] = j
                        k += 1
    return k


@parallel
def _count_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                 periodic_flag, periodic_length, start):
    n = positions.shape[0]
    empty = np.empty(0, np.uint32)
    for i in prange(n):
        start[i + 1] = _scan_grain(i, positions, radii, skin, cell, counts, cell_start,
                                   cell_items, periodic_flag, periodic_length, empty, 0)
    start[0] = 0
    for i in range(n):
        start[i + 1] += start[i]
    return start[n]


@parallel
def _fill_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                periodic_flag, periodic_length, start, partners):
    for i in prange(positions.shape[0]):
        _scan_grain(i, positions, radii, skin, cell, counts, cell_start, cell_items,
                    periodic_flag, periodic_length, partners, start[i])


@parallel
def _carry_history(start, partners, history, new_start, new_partners, new_history):
    """Copy each surviving pair's history from the old list; new pairs start at zero."""
    for i in prange(new_start.size - 1):
        for k in range(new_start[i], new_start[i + 1]):
            j = new_partners[k]
            found = -1
            for m in range(start[i], start[i + 1]):
                if partners[m] == j:
                    found = m
                    break
            for h in range(new_history.shape[1]):
                new_history[k, h] = history[found, h] if found >= 0 else 0.0


@kernel
def _reverse(start, partners, n, reverse_start, reverse_pairs):
    """CSR of the pairs in which each grain is the second member j."""
    reverse_start[:] = 0
    total = start[n]
    for k in range(total):
        reverse_start[partners[k] + 1] += 1
    for i in range(n):
        reverse_start[i + 1] += reverse_start[i]
    fill = reverse_start[:n].copy()
    for k in range(total):
        j = partners[k]
        reverse_pairs[fill[j]] = k
        fill[j] += 1


@parallel
def _wall_candidates(positions, radii, skin, kind, geometry, offset, wall_start, wall_ids,
                     write):
    """Count (write=False) or list the walls within R_i + skin of each grain."""
    n = positions.shape[0]
    for i in prange(n):
        k = 0
        for w in range(kind.size):
            dist, nx, ny, nz = wall_distance(kind, geometry, offset, w, positions[i, 0],
                                             positions[i, 1], positions[i, 2])
            if dist < radii[i] + skin:
                if write:
                    wall_ids[wall_start[i] + k] = w
                k += 1
        if not write:
            wall_start[i + 1] = k
    if not write:
        wall_start[0] = 0
        for i in range(n):
            wall_start[i + 1] += wall_start[i]
    return wall_start[n]


@kernel
def rebuild(positions, radii, skin, periodic_flag, periodic_lo, periodic_length,
            start, partners, history, scratch_start, scratch_partners, scratch_history,
            reverse_start, reverse_pairs,
            wall_kind, wall_geometry, wall_offset,
            wall_start, wall_ids, wall_history, scratch_wall_start, scratch_wall_ids,
            scratch_wall_history, reference_positions, reference_offset):
    """Rebuild pair and wall lists in place, carrying histories over.

    Returns (pairs needed, wall contacts needed); when either exceeds its capacity
    nothing but the wrapped positions has changed and the caller must grow the arrays.
    """
    n = positions.shape[0]
    wrap_positions(positions, periodic_flag, periodic_lo, periodic_length)
    cutoff = 2.0 * radii.max() + skin
    lo, size, counts = _grid(positions, cutoff, periodic_flag, periodic_lo, periodic_length)
    cell_start, cell_items, cell = _cell_sort(positions, lo, size, counts)
    needed = _count_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                          periodic_flag, periodic_length, scratch_start)
    wall_needed = _wall_candidates(positions, radii, skin, wall_kind, wall_geometry,
                                   wall_offset, scratch_wall_start, scratch_wall_ids, False)
    if needed > partners.size or wall_needed > wall_ids.size:
        return needed, wall_needed
    _fill_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                periodic_flag, periodic_length, scratch_start, scratch_partners)
    _carry_history(start, partners, history, scratch_start, scratch_partners, scratch_history)
    start[:] = scratch_start
    partners[:needed] = scratch_partners[:needed]
    history[:needed] = scratch_history[:needed]
    _reverse(start, partners, n, reverse_start, reverse_pairs)
    _wall_candidates(positions, radii, skin, wall_kind, wall_geometry, wall_offset,
                     scratch_wall_start, scratch_wall_ids, True)
    _carry_history(wall_start, wall_ids, wall_history, scratch_wall_start, scratch_wall_ids,
                   scratch_wall_history)
    wall_start[:] = scratch_wall_start
    wall_ids[:wall_needed] = scratch_wall_ids[:wall_needed]
    wall_history[:wall_needed] = scratch_wall_history[:wall_needed]
    reference_positions[:] = positions
    reference_offset[:] = wall_offset
    return needed, wall_needed
