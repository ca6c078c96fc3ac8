"""The two compiled passes over grains that every integrator is made of, dispatched by
integer id (ids.py).  A step of integrator k: for each stage s < STAGES[k]:
``before_force(k, s)``, forces, ``after_force(k, s)``.  Fixed grains (fixed[i] == 1)
never move.  Rotation uses each scheme's own formulas on the rotation vector (w for v,
alpha = torque/I for a: spheres and disks have isotropic inertia, so Euler's equations
reduce to I dw/dt = torque in any frame) and turns the orientation by the exact
rotation of that increment (core.rotation.rotate_quaternion); leap_frog turns it with
Omelyan's quaternion leap-frog instead (Oquendo Eq. 16-18).

``history`` (slots, N, 3): the scheme's history, translational slots first, then the
rotational ones (ids.SLOTS).  ``dim`` 2: the disks move in the x-y plane and turn about
z only, so the passes leave z and the spins about x and y alone (they hold zeros, which
the schemes would keep: the same numbers, a third less work per disk).  ``started``: 0 on the first step after the history was
(re)set, when multi-step schemes use their exact start-up formulas.
"""
import math

import numpy as np

from ...._jit import block, block_body, parallel, prange, scalar
from ....core.neighbors import min_image
from ....core.rotation import quaternion_leapfrog, rotate_quaternion
from ..contacts import gather_pairs, largest
from .beeman import beeman_correct, beeman_drift
from .gear import gear_correct, gear_drift
from .ids import (BEEMAN, GEAR3, LEAP_FROG, OPTIMIZED_VELOCITY_VERLET, SLOTS,
                  VELOCITY_VERLET)
from .verlet import verlet_correct, verlet_drift


@scalar
def drift(integrator, stage, h, started, vel, acc, history, base, i, d):
    """Coordinate increment of component d of grain i before the force of ``stage``."""
    if integrator <= OPTIMIZED_VELOCITY_VERLET:
        return verlet_drift(integrator, stage, h, started, vel, acc, history, base, i, d)
    if integrator == BEEMAN:
        return beeman_drift(h, started, vel, acc, history, base, i, d)
    return gear_drift(SLOTS[integrator], h, vel, acc, history, base, i, d)


@scalar
def correct(integrator, stage, h, started, a_new, vel, acc, history, base, i, d):
    """Velocity correction of component d after the force; returns the increment to apply
    after the force.  h = 0 (the priming evaluation) only stores the acceleration."""
    if h == 0.0:
        acc[i, d] = a_new
        return 0.0
    if integrator <= OPTIMIZED_VELOCITY_VERLET:
        return verlet_correct(integrator, stage, h, a_new, vel, acc, history, base, i, d)
    if integrator == BEEMAN:
        return beeman_correct(h, started, a_new, vel, acc, history, base, i, d)
    return gear_correct(integrator, SLOTS[integrator], h, a_new, vel, acc, history, base, i, d)


@scalar
def component(d, value, x, y, z):
    """(x, y, z) with component d replaced by ``value``."""
    if d == 0:
        return value, y, z
    if d == 1:
        return x, value, z
    return x, y, value


@scalar
def first_spin(dim):
    """The first rotational component that moves: x (0) in 3D, z (2) for 2D disks."""
    return 0 if dim == 3 else 2


@scalar
def turn(integrator, orientations, i, px, py, pz, wx, wy, wz, h):
    """Turn grain i by the rotation vector (px, py, pz) [rad]; leap_frog uses Omelyan's
    quaternion update with the half-step angular velocity (wx, wy, wz) [rad/s].
    Orientations of shape (0, 4): not followed (Simulation(orientations=False))."""
    if orientations.shape[0] == 0:
        return
    if integrator == LEAP_FROG:
        q = quaternion_leapfrog(orientations[i, 0], orientations[i, 1], orientations[i, 2],
                                orientations[i, 3], wx, wy, wz, h)
    else:
        q = rotate_quaternion(orientations[i, 0], orientations[i, 1], orientations[i, 2],
                              orientations[i, 3], px, py, pz)
    for c in range(4):
        orientations[i, c] = q[c]


@block_body
def drift_grain(i, integrator, stage, dt, started, dim, positions, velocities,
                angular_velocities, orientations, accelerations, angular_accelerations, fixed,
                history):
    """Drift/predict grain i before the force evaluation of ``stage`` (the loop body of
    ``before_force``, shared with the GPU kernels).  Compiled once and LLVM-inlined
    into before_force and _correct_rows: IR-inlined into both, it was typed twice and
    made numba's inlining pass superlinear (cold start 85 -> 55 s with the single
    call sites of drift and correct, BENCHMARKS.md)."""
    if fixed[i]:
        return
    rot = SLOTS[integrator]
    for d in range(dim):
        positions[i, d] += drift(integrator, stage, dt, started, velocities, accelerations,
                                 history, 0, i, d)
    px = py = pz = 0.0
    for d in range(first_spin(dim), 3):   # one call site: numba inlines each site anew
        p = drift(integrator, stage, dt, started, angular_velocities, angular_accelerations,
                  history, rot, i, d)
        px, py, pz = component(d, p, px, py, pz)
    turn(integrator, orientations, i, px, py, pz, angular_velocities[i, 0],
         angular_velocities[i, 1], angular_velocities[i, 2], dt)


@parallel
def before_force(integrator, stage, dt, started, dim, positions, velocities,
                 angular_velocities, orientations, accelerations, angular_accelerations, fixed,
                 history):
    """Drift/predict every free grain before the force evaluation of ``stage``."""
    for i in prange(positions.shape[0]):
        drift_grain(np.int64(i), integrator, stage, dt, started, dim, positions, velocities,
                    angular_velocities, orientations, accelerations, angular_accelerations,
                    fixed, history)


@scalar
def correct_grain(i, integrator, stage, dt, started, dim, f, forces, torques, masses,
                  inertias, positions, reference_positions, velocities, angular_velocities,
                  orientations, accelerations, angular_accelerations, fixed, periodic_flag,
                  periodic_length, history):
    """Grain i after the force evaluation (the loop body of ``after_force``, shared with
    the GPU kernels): stores its force and torque f (6, contacts.gather_pairs on the
    CPU, gather_grain on the GPU), corrects, turns.  Returns |r - r_ref|^2 [m^2],
    |v|^2 [m^2/s^2] and |a|^2 [m^2/s^4] for the half-skin bound."""
    rot = SLOTS[integrator]
    for d in range(3):
        forces[i, d] = f[d]
        torques[i, d] = f[3 + d]
    if not fixed[i]:
        inverse_mass = 1.0 / masses[i]
        inverse_inertia = 1.0 / inertias[i]
        for d in range(dim):
            step = correct(integrator, stage, dt, started, f[d] * inverse_mass, velocities,
                           accelerations, history, 0, i, d)
            if step != 0.0:     # folds away where the scheme's step is 0 (x + 0.0 does not)
                positions[i, d] += step
        px = py = pz = 0.0
        for d in range(first_spin(dim), 3):   # one call site, as in drift_grain
            alpha = f[3 + d] * inverse_inertia
            p = correct(integrator, stage, dt, started, alpha, angular_velocities,
                        angular_accelerations, history, rot, i, d)
            px, py, pz = component(d, p, px, py, pz)
        if px != 0.0 or py != 0.0 or pz != 0.0:
            turn(np.int64(VELOCITY_VERLET), orientations, i, px, py, pz, 0.0, 0.0, 0.0, dt)
    v2 = 0.0
    a2 = 0.0
    for d in range(dim):
        v2 += velocities[i, d] * velocities[i, d]
        a2 += accelerations[i, d] * accelerations[i, d]
    return displacement2(i, dim, positions, reference_positions, periodic_flag,
                         periodic_length), v2, a2


@scalar
def displacement2(i, dim, positions, reference_positions, periodic_flag, periodic_length):
    """|r_i - r_ref,i|^2 [m^2] over the dim components that move, the minimum image
    along periodic directions."""
    d2 = 0.0
    for d in range(dim):
        dx = min_image(positions[i, d] - reference_positions[i, d], periodic_flag[d],
                       periodic_length[d])
        d2 += dx * dx
    return d2


@block_body
def _correct_rows(lo, hi, integrator, stage, dt, started, dim, gravity, rows, drift_next):
    """gather_pairs and correct_grain for grains lo..hi-1, then, when ``drift_next``,
    the first drift of the next step (drift_grain, stage 0: one pass over the grains'
    arrays instead of two); returns max |r - r_ref| + max |v| dt + max |a| dt^2/2 over
    them [m], or with that drift done max |r - r_ref| after it (square roots once per
    block, not per grain; the drifted grains' v and a no longer read: gather + correct
    + drift of the 280-grain bed 3.9 -> 3.7 us).  The
    pairs listed by the block's grains (from start[lo] on) and their wall contacts are
    already in own (contacts._pair_block, _wall_block).  ``rows``: the arrays of
    _correct_block's arguments from own to history, in that order."""
    (own, start, reverse_start, reverse_pairs, pair_force, pair_torque_j, forces, torques,
     masses, inertias, positions, reference_positions, velocities, angular_velocities,
     orientations, accelerations, angular_accelerations, fixed, periodic_flag,
     periodic_length, history) = rows
    owned_from = start[lo]
    top_d2 = 0.0
    top_v2 = 0.0
    top_a2 = 0.0
    for i in range(lo, hi):
        f = gather_pairs(i, masses[i], gravity, own, reverse_start, reverse_pairs, owned_from,
                         pair_force, pair_torque_j)
        d2, v2, a2 = correct_grain(
            i, integrator, stage, dt, started, dim, f, forces, torques, masses, inertias,
            positions, reference_positions, velocities, angular_velocities, orientations,
            accelerations, angular_accelerations, fixed, periodic_flag, periodic_length,
            history)
        if drift_next:
            drift_grain(i, integrator, np.int64(0), dt, np.bool_(True), dim, positions,
                        velocities, angular_velocities, orientations, accelerations,
                        angular_accelerations, fixed, history)
            # drifted: the displacement itself, no bound on the drift needed
            d2 = displacement2(i, dim, positions, reference_positions, periodic_flag,
                               periodic_length)
            v2 = a2 = 0.0
        top_d2 = max(top_d2, d2)
        top_v2 = max(top_v2, v2)
        top_a2 = max(top_a2, a2)
    return math.sqrt(top_d2) + math.sqrt(top_v2) * dt + 0.5 * math.sqrt(top_a2) * dt * dt


@block
def _correct_block(lo, hi, integrator, stage, dt, started, dim, gravity, own, start,
                   reverse_start, reverse_pairs, pair_force, pair_torque_j, forces, torques,
                   masses, inertias, positions, reference_positions, velocities,
                   angular_velocities, orientations, accelerations, angular_accelerations,
                   fixed, periodic_flag, periodic_length, history, drift_next):
    """_correct_rows, compiled once as a serial function.  For the steps whose pass does
    the next drift (all but those that end a chunk or are checked), the schemes of the
    documents' experiments get copies of their own in which the integrator, the
    dimension and the drift are constants, so that the dispatch on them folds away:
    velocity Verlet (the default, Pérez's silo) in 3D and 2D (about 40 us of the 330 us
    of this pass on a 10 000-grain bed, one thread) and gear3 (Karrech's cyclic
    loading) in 3D (the 430-grain cyclic bed: gather + correct + drift 47.9 -> 16.6 us,
    the whole step 107 -> 77 us); the same numbers to the bit (BENCHMARKS.md).  The
    optimized velocity Verlet (Oquendo's oedometer) gained nothing from a copy of its
    own (the 280-grain step 122 us either way)."""
    rows = (own, start, reverse_start, reverse_pairs, pair_force, pair_torque_j, forces,
            torques, masses, inertias, positions, reference_positions, velocities,
            angular_velocities, orientations, accelerations, angular_accelerations, fixed,
            periodic_flag, periodic_length, history)
    # constants typed as the generic call's (no second compile of _correct_rows): LLVM
    # folds them after inlining
    if drift_next and dim == 3:
        if integrator == VELOCITY_VERLET:
            return _correct_rows(lo, hi, np.int64(VELOCITY_VERLET), np.int64(0), dt, started,
                                 np.int64(3), gravity, rows, np.bool_(True))
        if integrator == GEAR3:
            return _correct_rows(lo, hi, np.int64(GEAR3), np.int64(0), dt, started,
                                 np.int64(3), gravity, rows, np.bool_(True))
    if drift_next and dim == 2 and integrator == VELOCITY_VERLET:
        return _correct_rows(lo, hi, np.int64(VELOCITY_VERLET), np.int64(0), dt, started,
                             np.int64(2), gravity, rows, np.bool_(True))
    return _correct_rows(lo, hi, integrator, stage, dt, started, dim, gravity, rows,
                         drift_next)


@parallel
def after_force(integrator, stage, dt, started, dim, gravity, pairs, forces, torques, masses,
                inertias, positions, reference_positions, velocities, angular_velocities,
                orientations, accelerations, angular_accelerations, fixed, periodic_flag,
                periodic_length, history, block_scratch, drift_next):
    """Gather contact forces onto grains, correct velocities with the new accelerations
    (dt = 0 only stores the accelerations at start-up), and return a bound on how far
    any grain may be from where it was at the last neighbour build by the end of the
    next drift, max |r - r_ref| + max |v| dt + max |a| dt^2/2 [m] (maxima over grains),
    for the half-skin rule (the higher-order terms of Beeman and Gear are O(dt^3), far
    below the skin).  One pass over grains, in fixed blocks (one per entry of
    block_scratch, contacts.block_count), so the result does not depend on thread
    timing.  ``drift_next``: also the first drift of the next step (_correct_block);
    the bound is then the displacement itself, max |r - r_ref| after that drift.
    pairs : bundles.Pairs (its start, reverse lists, force, own and torque_j)."""
    own, start, reverse_start, reverse_pairs, pair_force, pair_torque_j = \
        pairs.own, pairs.start, pairs.reverse_start, pairs.reverse_pairs, pairs.force, \
        pairs.torque_j
    n = masses.size
    nblock = block_scratch.size
    if nblock == 1:    # no parallel region to enter (a few us per call); a plain int64 0
        block_scratch[0] = _correct_block(
            np.int64(0), n, integrator, stage, dt, started, dim, gravity, own, start,
            reverse_start, reverse_pairs, pair_force, pair_torque_j, forces, torques, masses,
            inertias, positions, reference_positions, velocities, angular_velocities,
            orientations, accelerations, angular_accelerations, fixed, periodic_flag,
            periodic_length, history, drift_next)
        return block_scratch[0]
    for b in prange(nblock):
        block_scratch[b] = _correct_block(
            b * n // nblock, (b + 1) * n // nblock, integrator, stage, dt, started, dim,
            gravity, own, start, reverse_start, reverse_pairs, pair_force, pair_torque_j,
            forces, torques, masses, inertias, positions, reference_positions, velocities,
            angular_velocities, orientations, accelerations, angular_accelerations, fixed,
            periodic_flag, periodic_length, history, drift_next)
    return largest(block_scratch[:nblock])
