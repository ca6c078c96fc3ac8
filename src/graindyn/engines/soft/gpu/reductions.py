"""Reductions over grains on the device: the wall totals and dissipated
energies of each force evaluation, and, from the correction kernel, the half-skin
displacement bound and the measures of engines/soft/loop._checks (non-finite values, largest
overlap, largest speed, energies), for each system of an ensemble (engines/soft/gpu/layout.py; one
system is the case K = 1).

Each is three steps: one row per at most ROW consecutive grains of one system (the
energy dissipated, the bound and the checks come as rows straight from the force and
correction kernels, reduced over each block by a tree in shared memory; the wall totals
are reduced by one thread per row, in grain order); ``fold`` reduces each column over the
rows of each system with one block per system (thread t takes rows t, t + width, ...
in order, then a tree; the width depends only on the system's own row count); one
thread per system applies the results.  No per-grain scratch array is needed.  The
order is fixed, so a run repeats to the last bit and system k of an ensemble equals
the same system alone; maxima and minima equal the CPU's, sums differ from its
grain-order sums only by association.
"""
import math

import numpy as np
from numba import cuda, float64

from .. import loop

FOLD = 256             # most threads of a folding block (a power of two)
SUM, MAX, MIN = 0, 1, 2
# columns of the correction kernel's rows: the squared displacement since the last
# build, speed and acceleration (the bound), then the checks: any non-finite value,
# squared speed, overlap [m], kinetic energy [J], lowest height [m], sum of mass times
# height [kg m] and of mass [kg] (free grains), and how each folds
DISPLACED, SPEED, ACCELERATION, BAD, SPEED2, OVERLAP, KINETIC, LOW, MASS_HEIGHT, MASS = \
    range(10)
COLUMN_OPS = (MAX, MAX, MAX, MAX, MAX, MAX, SUM, MIN, SUM, SUM)
_KERNELS = {}


def fold_width(nrows):
    """Threads folding nrows rows: a power of two, at most FOLD."""
    width = 1
    while width < min(nrows, FOLD):
        width *= 2
    return width


def fold(kernels, layout, partial, ops, out):
    """out[k, q] = SUM, MAX or MIN (device array ops[q]) of partial[:, q] over the rows
    of system k (layout: a gpu.layout.Layout with its device tables)."""
    kernels["fold"][layout.k, fold_width(layout.max_rows)](partial, layout.dev["rb"], ops,
                                                             out)


def ops_array(ops):
    """The device array of fold operations."""
    return cuda.to_device(np.asarray(ops, np.int64))


@cuda.jit(device=True)
def block_rows(buf, values, row, ops):
    """Reduce buf[t, q] over the threads of the block (SUM, MAX or MIN by ops[q], a
    fixed tree) into row[q]; every thread of the block must call it."""
    t = cuda.threadIdx.x
    width = cuda.blockDim.x
    cuda.syncthreads()
    step = 1
    while step < width:
        step *= 2
    step //= 2
    while step > 0:
        if t < step and t + step < width:
            for q in range(values):
                if ops[q] == SUM:
                    buf[t, q] += buf[t + step, q]
                elif ops[q] == MAX:
                    buf[t, q] = max(buf[t, q], buf[t + step, q])
                else:
                    buf[t, q] = min(buf[t, q], buf[t + step, q])
        cuda.syncthreads()
        step //= 2
    if t == 0:
        for q in range(values):
            row[q] = buf[0, q]


@cuda.jit(device=True)
def move_bound(folded, dt):
    """The displacement bound of the half-skin rule from a system's folded rows [m]:
    max |r - r_ref| + max |v| dt + max |a| dt^2 / 2."""
    return (math.sqrt(folded[DISPLACED]) + math.sqrt(folded[SPEED]) * dt
            + 0.5 * math.sqrt(folded[ACCELERATION]) * dt * dt)


@cuda.jit(device=True)
def potential_energy(folded, clock):
    """Potential energy [J] of a system's free grains above the lowest, from its
    folded check columns: g (sum m h - h_low sum m)."""
    g = math.sqrt(clock[loop.GX] ** 2 + clock[loop.GY] ** 2 + clock[loop.GZ] ** 2)
    if g == 0.0 or folded[MASS] == 0.0:
        return 0.0
    return g * (folded[MASS_HEIGHT] - folded[LOW] * folded[MASS])


def kernels():
    """The reduction kernels (compiled on first use, once per process)."""
    if _KERNELS:
        return _KERNELS

    @cuda.jit(device=True)
    def width_of(nrows):
        width = 1
        while width < min(nrows, FOLD):
            width *= 2
        return width

    @cuda.jit
    def fold(partial, rb, ops, out):
        """out[k, q] = sum, max or min (ops[q]) of column q over the rows of system k
        (block k)."""
        buf = cuda.shared.array(FOLD, float64)
        k = cuda.blockIdx.x
        t = cuda.threadIdx.x
        first, last = rb[k], rb[k + 1]
        width = width_of(last - first)
        for q in range(partial.shape[1]):
            op = ops[q]
            acc = 0.0 if op == SUM else (-math.inf if op == MAX else math.inf)
            if t < width:
                for c in range(first + t, last, width):
                    if op == SUM:
                        acc += partial[c, q]
                    elif op == MAX:
                        acc = max(acc, partial[c, q])
                    else:
                        acc = min(acc, partial[c, q])
            if width == 1:          # one row (the whole block agrees): no tree
                if t == 0:
                    out[k, q] = acc
                continue
            buf[t] = acc
            cuda.syncthreads()
            step = width // 2
            while step > 0:
                if t < step:
                    if op == SUM:
                        buf[t] += buf[t + step]
                    elif op == MAX:
                        buf[t] = max(buf[t], buf[t + step])
                    else:
                        buf[t] = min(buf[t], buf[t + step])
                cuda.syncthreads()
                step //= 2
            if t == 0:
                out[k, q] = buf[0]
            cuda.syncthreads()

    @cuda.jit
    def totals_partial(row_first, row_system, wb, mask, wall_start, wall_ids,
                       contact_force, velocity, lost, partial):
        """Row c: force of its grains on each wall of their system (3 per wall, local
        wall order), wall power, and the normal and tangential energy they dissipated
        (lost[c], from the force kernel)."""
        c = cuda.grid(1)
        if c >= partial.shape[0]:
            return
        k = row_system[c]
        if mask[k] == 0:
            return
        nw = (partial.shape[1] - 3) // 3
        for q in range(partial.shape[1]):
            partial[c, q] = 0.0
        partial[c, 3 * nw + 1] = lost[c, 0]
        partial[c, 3 * nw + 2] = lost[c, 1]
        for i in range(row_first[c], row_first[c + 1]):
            for q in range(wall_start[i + k], wall_start[i + k + 1]):
                w = wall_ids[q]
                for d in range(3):
                    partial[c, 3 * (w - wb[k]) + d] -= contact_force[q, d]
                    partial[c, 3 * nw] += contact_force[q, d] * velocity[w, d]

    @cuda.jit
    def totals_apply(folded, wb, mask, force, clock, scale, divisor):
        """Wall forces [N] of system k; its dissipated energy [J] and wall work [J]
        (power times the step's share, scale * dt / divisor) added to its clock."""
        k = cuda.grid(1)
        if k >= mask.size or mask[k] == 0:
            return
        nw = (folded.shape[1] - 3) // 3
        for w in range(wb[k + 1] - wb[k]):
            for d in range(3):
                force[wb[k] + w, d] = folded[k, 3 * w + d]
        clock[k, loop.DISS_N] += folded[k, 3 * nw + 1]
        clock[k, loop.DISS_T] += folded[k, 3 * nw + 2]
        clock[k, loop.WALL_WORK] += folded[k, 3 * nw] * (scale * clock[k, loop.DT] / divisor)

    @cuda.jit
    def bound_apply(folded, mask, clock, scale):
        """clock[k, MOVE]: move_bound of system k's folded rows."""
        k = cuda.grid(1)
        if k < mask.size and mask[k] != 0:
            clock[k, loop.MOVE] = move_bound(folded[k], scale * clock[k, loop.DT])

    _KERNELS.update(fold=fold, totals_partial=totals_partial, totals_apply=totals_apply,
                    bound_apply=bound_apply)
    return _KERNELS
