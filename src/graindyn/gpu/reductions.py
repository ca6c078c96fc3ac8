"""Reductions over grains on the device (issue 6): the wall totals and dissipated
energies of each force evaluation, the half-skin displacement bound, and the checks
of core/loop._checks (non-finite values, largest overlap, largest speed, energies).

Each is three steps: one row per CHUNK consecutive grains (the energy dissipated and
the displacement bound come as rows straight from the force and correction kernels,
reduced over each block of CHUNK threads by a tree in shared memory; the others are
reduced by one thread per row, in grain order); ``fold`` reduces each column over the
rows with one block (thread t takes rows t, t + width, ... in order, then a tree);
one thread applies the results.  No per-grain scratch array is needed.  The order is fixed, so a run repeats to the last
bit; maxima and minima equal the CPU's, sums differ from its grain-order sums only by
association.
"""
import math

import numpy as np
from numba import cuda, float64

from ..core import loop

CHUNK = 128            # grains per partial row
FOLD = 256             # most threads of the folding block (a power of two)
SUM, MAX, MIN = 0, 1, 2
# columns of the check partials, and how each folds
BAD, SPEED2, OVERLAP, KINETIC, LOW, POTENTIAL = range(6)
CHECK_OPS = (MAX, MAX, MAX, SUM, MIN, SUM)
_KERNELS = {}


def rows(n):
    """Partial rows for n grains."""
    return max(1, (n + CHUNK - 1) // CHUNK)


def fold_width(nrows):
    """Threads of the folding block for nrows rows: a power of two, at most FOLD."""
    width = 1
    while width < min(nrows, FOLD):
        width *= 2
    return width


def fold(kernels, partial, ops, out):
    """out[q] = SUM, MAX or MIN (device array ops[q]) of partial[:, q] over the rows."""
    kernels["fold"][1, fold_width(partial.shape[0])](partial, ops, out)


def ops_array(ops):
    """The device array of fold operations."""
    return cuda.to_device(np.asarray(ops, np.int64))


def kernels():
    """The reduction kernels (compiled on first use, once per process)."""
    if _KERNELS:
        return _KERNELS

    @cuda.jit
    def fold(partial, ops, out):
        """out[q] = sum, max or min (ops[q]) of column q over the rows (one block)."""
        buf = cuda.shared.array(FOLD, float64)
        t = cuda.threadIdx.x
        width = cuda.blockDim.x
        for q in range(partial.shape[1]):
            op = ops[q]
            acc = 0.0 if op == SUM else (-math.inf if op == MAX else math.inf)
            for c in range(t, partial.shape[0], width):
                if op == SUM:
                    acc += partial[c, q]
                elif op == MAX:
                    acc = max(acc, partial[c, q])
                else:
                    acc = min(acc, partial[c, q])
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
                out[q] = buf[0]
            cuda.syncthreads()

    @cuda.jit
    def totals_partial(wall_start, wall_ids, contact_force, velocity, lost, partial):
        """Row c: force of grains c*CHUNK... on each wall (3 W), wall power, and the
        normal and tangential energy they dissipated (lost[c], from the force kernel)."""
        c = cuda.grid(1)
        if c >= partial.shape[0]:
            return
        nw = velocity.shape[0]
        for q in range(partial.shape[1]):
            partial[c, q] = 0.0
        partial[c, 3 * nw + 1] = lost[c, 0]
        partial[c, 3 * nw + 2] = lost[c, 1]
        for i in range(c * CHUNK, min(wall_start.size - 1, (c + 1) * CHUNK)):
            for q in range(wall_start[i], wall_start[i + 1]):
                w = wall_ids[q]
                for d in range(3):
                    partial[c, 3 * w + d] -= contact_force[q, d]
                    partial[c, 3 * nw] += contact_force[q, d] * velocity[w, d]

    @cuda.jit
    def totals_apply(folded, force, clock, share):
        """Wall forces [N]; dissipated energy [J] and wall work [J] added to the clock."""
        if cuda.grid(1) != 0:
            return
        nw = force.shape[0]
        for w in range(nw):
            for d in range(3):
                force[w, d] = folded[3 * w + d]
        clock[loop.DISS_N] += folded[3 * nw + 1]
        clock[loop.DISS_T] += folded[3 * nw + 2]
        clock[loop.WALL_WORK] += folded[3 * nw] * share

    @cuda.jit
    def bound_apply(folded, dt, clock):
        """clock[MOVE] = max |r - r_ref| + max |v| dt + max |a| dt^2 / 2."""
        if cuda.grid(1) == 0:
            clock[loop.MOVE] = (math.sqrt(folded[0]) + math.sqrt(folded[1]) * dt
                                + 0.5 * math.sqrt(folded[2]) * dt * dt)

    @cuda.jit
    def checks_partial(positions, velocities, angular_velocities, forces, masses, inertias,
                       fixed, max_overlap, gravity, reset, partial):
        """Row c: any non-finite position, velocity or force; largest squared speed of a
        free grain; largest overlap (reset to 0 when ``reset``); kinetic energy [J]
        and lowest height [m] of the free grains."""
        c = cuda.grid(1)
        if c >= partial.shape[0]:
            return
        g = math.sqrt(gravity[0] ** 2 + gravity[1] ** 2 + gravity[2] ** 2)
        bad = speed2 = worst = kinetic = 0.0
        low = math.inf
        for i in range(c * CHUNK, min(masses.shape[0], (c + 1) * CHUNK)):
            v2 = 0.0
            w2 = 0.0
            for d in range(3):
                if not (math.isfinite(positions[i, d]) and math.isfinite(velocities[i, d])
                        and math.isfinite(forces[i, d])):
                    bad = 1.0
                v2 += velocities[i, d] ** 2
                w2 += angular_velocities[i, d] ** 2
            worst = max(worst, max_overlap[i])
            if reset:
                max_overlap[i] = 0.0
            if not fixed[i]:
                speed2 = max(speed2, v2)
                kinetic += 0.5 * masses[i] * v2 + 0.5 * inertias[i] * w2
                if g > 0.0:
                    low = min(low, -(positions[i, 0] * gravity[0] + positions[i, 1]
                                     * gravity[1] + positions[i, 2] * gravity[2]) / g)
        partial[c, BAD] = bad
        partial[c, SPEED2] = speed2
        partial[c, OVERLAP] = worst
        partial[c, KINETIC] = kinetic
        partial[c, LOW] = low

    @cuda.jit
    def potential_partial(positions, masses, fixed, gravity, out, partial):
        """Row c: potential energy [J] of free grains above the lowest (out[LOW])."""
        c = cuda.grid(1)
        if c >= partial.shape[0]:
            return
        g = math.sqrt(gravity[0] ** 2 + gravity[1] ** 2 + gravity[2] ** 2)
        potential = 0.0
        if g > 0.0:
            for i in range(c * CHUNK, min(masses.shape[0], (c + 1) * CHUNK)):
                if not fixed[i]:
                    h = -(positions[i, 0] * gravity[0] + positions[i, 1] * gravity[1]
                          + positions[i, 2] * gravity[2]) / g
                    potential += masses[i] * g * (h - out[LOW])
        partial[c, POTENTIAL] = potential

    _KERNELS.update(locals())
    return _KERNELS
