"""Reductions over grains on the device (issue 6): the wall totals and dissipated
energies of each force evaluation, the half-skin displacement bound, and the checks
of core/loop._checks (non-finite values, largest overlap, largest speed, energies).

Each is two kernels: one thread per CHUNK consecutive grains reduces them in grain
order into a row of ``partial``, then one thread reduces the rows in order.  The order
is fixed, so a run repeats to the last bit; maxima and minima equal the CPU's, sums
differ from its grain-order sums only by association.
"""
import math

from numba import cuda

from ..core import loop

CHUNK = 128            # grains per partial row
# columns of the check partials
BAD, SPEED2, OVERLAP, KINETIC, LOW, POTENTIAL = range(6)
_KERNELS = {}


def rows(n):
    """Partial rows for n grains."""
    return max(1, (n + CHUNK - 1) // CHUNK)


def kernels():
    """The reduction kernels (compiled on first use, once per process)."""
    if _KERNELS:
        return _KERNELS

    @cuda.jit
    def totals_partial(wall_start, wall_ids, contact_force, velocity, dissipation, partial):
        """Row c: force of grains c*CHUNK... on each wall (3 W), wall power, normal and
        tangential dissipation."""
        c = cuda.grid(1)
        if c >= partial.shape[0]:
            return
        nw = velocity.shape[0]
        for q in range(partial.shape[1]):
            partial[c, q] = 0.0
        for i in range(c * CHUNK, min(dissipation.shape[0], (c + 1) * CHUNK)):
            partial[c, 3 * nw + 1] += dissipation[i, 0]
            partial[c, 3 * nw + 2] += dissipation[i, 1]
            for q in range(wall_start[i], wall_start[i + 1]):
                w = wall_ids[q]
                for d in range(3):
                    partial[c, 3 * w + d] -= contact_force[q, d]
                    partial[c, 3 * nw] += contact_force[q, d] * velocity[w, d]

    @cuda.jit
    def totals_finish(partial, force, clock, share):
        """Wall forces [N]; dissipated energy [J] and wall work [J] added to the clock."""
        if cuda.grid(1) != 0:
            return
        nw = force.shape[0]
        for w in range(nw):
            for d in range(3):
                f = 0.0
                for c in range(partial.shape[0]):
                    f += partial[c, 3 * w + d]
                force[w, d] = f
        power = lost_n = lost_t = 0.0
        for c in range(partial.shape[0]):
            power += partial[c, 3 * nw]
            lost_n += partial[c, 3 * nw + 1]
            lost_t += partial[c, 3 * nw + 2]
        clock[loop.DISS_N] += lost_n
        clock[loop.DISS_T] += lost_t
        clock[loop.WALL_WORK] += power * share

    @cuda.jit
    def bound_partial(squares, partial):
        c = cuda.grid(1)
        if c >= partial.shape[0]:
            return
        for k in range(3):
            partial[c, k] = 0.0
        for i in range(c * CHUNK, min(squares.shape[0], (c + 1) * CHUNK)):
            for k in range(3):
                partial[c, k] = max(partial[c, k], squares[i, k])

    @cuda.jit
    def bound_finish(partial, dt, clock):
        """clock[MOVE] = max |r - r_ref| + max |v| dt + max |a| dt^2 / 2."""
        if cuda.grid(1) != 0:
            return
        d2 = v2 = a2 = 0.0
        for c in range(partial.shape[0]):
            d2 = max(d2, partial[c, 0])
            v2 = max(v2, partial[c, 1])
            a2 = max(a2, partial[c, 2])
        clock[loop.MOVE] = math.sqrt(d2) + math.sqrt(v2) * dt + 0.5 * math.sqrt(a2) * dt * dt

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
    def checks_finish(partial, out):
        if cuda.grid(1) != 0:
            return
        out[BAD] = out[SPEED2] = out[OVERLAP] = out[KINETIC] = 0.0
        out[LOW] = math.inf
        for c in range(partial.shape[0]):
            for k in (BAD, SPEED2, OVERLAP):
                out[k] = max(out[k], partial[c, k])
            out[KINETIC] += partial[c, KINETIC]
            out[LOW] = min(out[LOW], partial[c, LOW])

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

    @cuda.jit
    def potential_finish(partial, out):
        if cuda.grid(1) != 0:
            return
        out[POTENTIAL] = 0.0
        for c in range(partial.shape[0]):
            out[POTENTIAL] += partial[c, POTENTIAL]

    _KERNELS.update(locals())
    return _KERNELS
