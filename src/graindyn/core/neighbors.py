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

from .._jit import inlined, kernel, parallel, prange, scalar
from .walls import wall_reach


@scalar
def min_image(dx, periodic, length):
    """Minimum-image separation along an axis of period ``length`` (scalar arguments:
    arrays passed to a non-inlined function cost reference counting in hot loops)."""
    if periodic:
        dx -= length * math.floor(dx / length + 0.5)
    return dx


@scalar
def wrap_coordinate(x, lo, length):
    """A coordinate brought back into [lo, lo + L) along a periodic axis."""
    return lo + (x - lo) % length


@kernel
def wrap_positions(positions, periodic_flag, periodic_lo, periodic_length):
    """Bring positions back into [lo, lo + L) along periodic axes."""
    for d in range(3):
        if periodic_flag[d]:
            for i in range(positions.shape[0]):
                positions[i, d] = wrap_coordinate(positions[i, d], periodic_lo[d],
                                                  periodic_length[d])


@kernel
def grid_from_extent(low, high, n, cutoff, periodic_flag, periodic_lo, periodic_length,
                     origin, size, counts):
    """Cell grid of at least ``cutoff`` [m] over the box [low, high] of N grains (periodic
    axes span their period): writes origin (3), cell size (3) and cell counts (3).
    Allocates nothing, so the GPU builds its grid with the same function."""
    for d in range(3):
        if periodic_flag[d]:
            origin[d] = periodic_lo[d]
            size[d] = periodic_length[d]
        else:
            origin[d] = low[d]
            size[d] = high[d] - low[d]
        # grains flung far apart by a blow-up: cap before converting to int (the
        # coarsening below brings the grid back to O(N) cells)
        counts[d] = max(1, int(min(size[d] / cutoff, 1e6)))
    # a dilute cloud spread far apart: coarsen so that the cells stay O(N)
    while counts[0] * counts[1] * counts[2] > 4 * n + 64:
        for d in range(3):
            counts[d] = max(1, counts[d] // 2)
    for d in range(3):
        size[d] = size[d] / counts[d] if periodic_flag[d] else max(size[d] / counts[d],
                                                                    cutoff)


@kernel
def cell_grid(positions, cutoff, periodic_flag, periodic_lo, periodic_length):
    """Cell grid of the current positions: (origin, size, counts)."""
    low = np.empty(3)
    high = np.empty(3)
    for d in range(3):
        low[d] = high[d] = positions[0, d]
        for i in range(positions.shape[0]):
            low[d] = min(low[d], positions[i, d])
            high[d] = max(high[d], positions[i, d])
    origin = np.empty(3)
    size = np.empty(3)
    counts = np.empty(3, np.int64)
    grid_from_extent(low, high, positions.shape[0], cutoff, periodic_flag, periodic_lo,
                     periodic_length, origin, size, counts)
    return origin, size, counts


@scalar
def cell_of(x, lo, size, count):
    c = int((x - lo) / size)
    return min(max(c, 0), count - 1)


@scalar
def cell_id(x, y, z, origin, size, counts):
    """Index of the cell holding the point (x, y, z) (points outside go to the edge)."""
    return (cell_of(x, origin[0], size[0], counts[0]) * counts[1]
            + cell_of(y, origin[1], size[1], counts[1])) * counts[2] \
        + cell_of(z, origin[2], size[2], counts[2])


@kernel
def cell_sort(positions, origin, size, counts):
    """Counting sort of grains by cell: (cell_start (C+1), cell_items (N), cell (N));
    within a cell the grains are in increasing index."""
    n = positions.shape[0]
    ncell = counts[0] * counts[1] * counts[2]
    cell = np.empty(n, np.int64)
    start = np.zeros(ncell + 1, np.int64)
    for i in range(n):
        c = cell_id(positions[i, 0], positions[i, 1], positions[i, 2], origin, size, counts)
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


@scalar
def neighbour_cell(c, o, count, periodic):
    """The o-th (0, 1, 2) neighbouring cell of cell c along an axis of ``count`` cells,
    or -1 when there is none (outside a wall, or already visited on a short period)."""
    if periodic:
        if count >= 3:
            return (c + o - 1) % count
        return o if o < count else -1
    a = c + o - 1
    return a if 0 <= a < count else -1


@inlined
def scan_grain(i, positions, radii, skin, cell, counts, cell_start, cell_items,
               periodic_flag, periodic_length, write, out, base):
    """Count the partners j > i of grain i, writing them at out[base:] when ``write``;
    in the order of cells, then of grain index (identical on CPU and GPU)."""
    c = cell[i]
    cz = c % counts[2]
    cy = (c // counts[2]) % counts[1]
    cx = c // (counts[1] * counts[2])
    k = 0
    for ox in range(3):
        ax = neighbour_cell(cx, ox, counts[0], periodic_flag[0])
        if ax < 0:
            continue
        for oy in range(3):
            ay = neighbour_cell(cy, oy, counts[1], periodic_flag[1])
            if ay < 0:
                continue
            for oz in range(3):
                az = neighbour_cell(cz, oz, counts[2], periodic_flag[2])
                if az < 0:
                    continue
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
                        if write:
                            out[base + k] = j
                        k += 1
    return k


@parallel
def _count_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                 periodic_flag, periodic_length, start):
    n = positions.shape[0]
    for i in prange(n):
        # typed, not literal, arguments: one compile of scan_grain for both loops
        start[i + 1] = scan_grain(np.int64(i), positions, radii, skin, cell, counts,
                                  cell_start, cell_items, periodic_flag, periodic_length,
                                  np.bool_(False), start, np.int64(0))
    start[0] = 0
    for i in range(n):
        start[i + 1] += start[i]
    return start[n]


@parallel
def _fill_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                periodic_flag, periodic_length, start, partners):
    for i in prange(positions.shape[0]):
        scan_grain(np.int64(i), positions, radii, skin, cell, counts, cell_start, cell_items,
                   periodic_flag, periodic_length, np.bool_(True), partners, start[i])


@inlined
def carry_row(i, start, partners, history, new_start, new_partners, new_history):
    """Copy grain i's surviving pairs' history from the old list; new pairs start at 0."""
    for k in range(new_start[i], new_start[i + 1]):
        j = new_partners[k]
        found = -1
        for m in range(start[i], start[i + 1]):
            if partners[m] == j:
                found = m
                break
        for h in range(new_history.shape[1]):
            new_history[k, h] = history[found, h] if found >= 0 else 0.0


@parallel
def carry_history(start, partners, history, new_start, new_partners, new_history):
    for i in prange(new_start.size - 1):
        carry_row(i, start, partners, history, new_start, new_partners, new_history)


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


@kernel
def list_owners(start, n, owner):
    """owner[k] = i for every pair (or wall candidate) k that grain i lists, read by
    the CPU's walks over pairs and wall candidates (contacts._pair_block, _wall_block)."""
    for i in range(n):
        for k in range(start[i], start[i + 1]):
            owner[k] = i


@inlined
def wall_row(i, positions, radii, skin, kind, geometry, offset, write, wall_ids, base):
    """Count the walls within R_i + skin of grain i (walls.wall_reach), writing them at
    wall_ids[base:] when ``write``."""
    k = 0
    for w in range(kind.size):
        dist = wall_reach(kind, geometry, offset, w, positions[i, 0], positions[i, 1],
                          positions[i, 2])
        if dist < radii[i] + skin:
            if write:
                wall_ids[base + k] = w
            k += 1
    return k


@parallel
def _wall_candidates(positions, radii, skin, kind, geometry, offset, wall_start, wall_ids,
                     write):
    """Count (write=False) or list the walls within R_i + skin of each grain."""
    n = positions.shape[0]
    for i in prange(n):
        k = wall_row(np.int64(i), positions, radii, skin, kind, geometry, offset, write,
                     wall_ids, wall_start[i])
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
    The new lists are made in the scratch arrays, then copied over the old ones;
    scratch_partners and scratch_wall_ids then hold the grain of each pair and wall
    candidate until the next rebuild (list_owners).
    """
    n = positions.shape[0]
    wrap_positions(positions, periodic_flag, periodic_lo, periodic_length)
    cutoff = 2.0 * radii.max() + skin
    origin, size, counts = cell_grid(positions, cutoff, periodic_flag, periodic_lo,
                                 periodic_length)
    cell_start, cell_items, cell = cell_sort(positions, origin, size, counts)
    needed = _count_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                          periodic_flag, periodic_length, scratch_start)
    # write as a typed bool, not a literal: one compile for both calls
    wall_needed = _wall_candidates(positions, radii, skin, wall_kind, wall_geometry,
                                   wall_offset, scratch_wall_start, scratch_wall_ids,
                                   np.bool_(False))
    if needed > partners.size or wall_needed > wall_ids.size:
        return needed, wall_needed
    _fill_pairs(positions, radii, skin, cell, counts, cell_start, cell_items,
                periodic_flag, periodic_length, scratch_start, scratch_partners)
    carry_history(start, partners, history, scratch_start, scratch_partners, scratch_history)
    start[:] = scratch_start
    partners[:needed] = scratch_partners[:needed]
    history[:needed] = scratch_history[:needed]
    _reverse(start, partners, n, reverse_start, reverse_pairs)
    list_owners(start, n, scratch_partners)
    _wall_candidates(positions, radii, skin, wall_kind, wall_geometry, wall_offset,
                     scratch_wall_start, scratch_wall_ids, np.bool_(True))
    carry_history(wall_start, wall_ids, wall_history, scratch_wall_start, scratch_wall_ids,
                   scratch_wall_history)
    wall_start[:] = scratch_wall_start
    wall_ids[:wall_needed] = scratch_wall_ids[:wall_needed]
    wall_history[:wall_needed] = scratch_wall_history[:wall_needed]
    list_owners(wall_start, n, scratch_wall_ids)
    reference_positions[:] = positions
    reference_offset[:] = wall_offset
    return needed, wall_needed
