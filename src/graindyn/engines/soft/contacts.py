"""Contact forces: pair geometry -> physics.contact_force -> per-contact arrays, and the
deterministic gather of those arrays onto grains (each grain sums its own contacts in
fixed order: no atomics, same numbers for the same thread count).  A grain's pairs are
listed with the grain of lower index, which computes them: it sums their force and
torque on itself as it goes (``own``) and stores for each pair what the other grain
needs (the force, and the torque on that grain).  The gather runs inside the
integrator's pass over grains (integrators.after_force).

On the CPU the touching pairs of a block of grains are gathered CAP at a time and
their law evaluated in SIMD lanes by a loop compiled for the model (engines/soft/law_loop.py,
_pair_block); the GPU evaluates them one by one per grain (pair_row).  Both give the
same pair forces, to the bit.  The CPU's block also adds a pair's force and torque to
its second grain's ``own`` when that grain is in the block (one thread owns the whole
block), so the gather reads back only the pairs that cross blocks (``owned_from``);
its wall contacts are added to ``own`` too (_wall_block).  The GPU gathers every pair
and every wall contact.  Only the order of the sums differs.

Collisions: the last history column of every contact is its touching mark (``touch``):
1.0 while the contact is closed, zeroed with the rest of its row when it opens
(_release), and carried over neighbour rebuilds and into snapshots with the history.
A contact found touching with its mark at 0 starts there: a collision, which the CPU
counts by block (grain pairs and wall contacts, contact_forces), in grain order; the
GPU sets the mark (pair_row, wall_row) but does not count.

Geometry (Oquendo Eq. 3-4): n = (r_i - r_j)/|r_i - r_j|, overlap h = R_i + R_j - |r_i - r_j|,
the contact point sits at R'_i = R_i - h R_j/(R_i + R_j) from grain i, and the relative
velocity of i at that point is v_i - v_j - (R'_i w_i + R'_j w_j) x n.
"""
import numpy as np

from ..._jit import block, block_body, parallel, prange, scalar
from ...core.neighbors import min_image
from ...core.walls import wall_distance
from ...physics.contact import contact_release
from .law_loop import (CAP, DVX, FIXED_I, FIXED_J, HISTORY, M_I, M_J, OUTPUT, PARAMS, R_I, R_J,
                       RATIO, STRIDE, SX, SY, SZ, TABLE, W_I, W_J, call_law, call_walk,
                       stage_geometry)
from .response import contact_geometry, contact_response

# most blocks of grains a pass hands to threads (Simulation.block_scratch has this size)
MAX_BLOCKS = 64
SERIAL = 128        # fewer grains per thread than this: one block (block_count)


@scalar
def _release(model, params, a, b, r_eff, history, force, torque, k):
    """A contact k that opened: returns the energy [J] left in its history springs (lost
    with the history, physics.contact.contact_release) and zeroes its history, force and
    torque rows."""
    lost = contact_release(model, params, a, b, r_eff, history, k)
    for h in range(history.shape[1]):
        history[k, h] = 0.0
    for d in range(3):
        force[k, d] = 0.0
        torque[k, d] = 0.0
    return lost


@scalar
def touch(history, k):
    """Set the touching mark of contact k (its last history column, 1.0) and return 1
    if it was not set: the contact starts at this evaluation, a collision; else 0."""
    mark = history.shape[1] - 1
    started = history[k, mark] == 0.0
    history[k, mark] = 1.0
    return np.int64(started)


@scalar
def grain_row(i, positions, radii, masses, materials):
    """Position (3) [m], radius [m], mass [kg] and material of grain i."""
    return (positions[i, 0], positions[i, 1], positions[i, 2], radii[i], masses[i],
            materials[i])


@scalar
def separation(j, xi, yi, zi, positions, px, py, pz, lx, ly, lz):
    """r_i - r_j [m] (3), the minimum image along periodic directions."""
    return (min_image(xi - positions[j, 0], px, lx), min_image(yi - positions[j, 1], py, ly),
            min_image(zi - positions[j, 2], pz, lz))


@scalar
def pair_geometry(i, j, xi, yi, zi, r_i, m_i, positions, radii, masses, fixed, px, py, pz,
                  lx, ly, lz):
    """Pair (i, j) with i's position, radius and mass given: (touching, then
    contact_geometry's values; for an open pair only R* [m] is set)."""
    dx, dy, dz = separation(j, xi, yi, zi, positions, px, py, pz, lx, ly, lz)
    r_j = radii[j]
    rsum = r_i + r_j
    if dx * dx + dy * dy + dz * dz >= rsum * rsum:
        return False, 0.0, 0.0, 0.0, 0.0, r_i * r_j / rsum, 0.0, 0.0, 0.0, 0.0
    overlap, ratio, lever_i, lever_j, r_eff, m_eff, nx, ny, nz = contact_geometry(
        dx, dy, dz, r_i, r_j, m_i, masses[j], fixed[i], fixed[j])
    return True, overlap, ratio, lever_i, lever_j, r_eff, m_eff, nx, ny, nz


@scalar
def opened(model, params, a, b, r_eff, history, pair_force, pair_torque_j, k):
    """Pair k not touching: the energy [J] its history springs held, if it had opened
    only now (_release), else 0.  The torque row counts too: a touching pair whose
    force is exactly zero (a repulsive-only law at rest) may leave it stale when the CPU
    does not store it (_flush), and a rebuild hands the slot to another pair."""
    dirty = pair_force[k, 0] != 0.0 or pair_force[k, 1] != 0.0 or pair_force[k, 2] != 0.0
    for d in range(3):
        dirty = dirty or pair_torque_j[k, d] != 0.0
    for h in range(history.shape[1]):
        dirty = dirty or history[k, h] != 0.0
    if dirty:
        return _release(model, params, a, b, r_eff, history, pair_force, pair_torque_j, k)
    return 0.0


@scalar
def pair_row(i, model, params, positions, velocities, angular_velocities, radii, masses,
             materials, fixed, periodic_flag, periodic_length, start, partners, history,
             pair_force, own, pair_torque_j, max_overlap, dt):
    """The pairs listed by grain i, one contact after the other (the GPU's pair kernel;
    the CPU batches them, _pair_block): writes their forces, touching marks (touch),
    own[i] and max_overlap[i]; returns the normal and tangential energy dissipated [J]."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    px, py, pz = periodic_flag[0], periodic_flag[1], periodic_flag[2]
    lx, ly, lz = periodic_length[0], periodic_length[1], periodic_length[2]
    worst = max_overlap[i]
    # grain i's data, loaded once (the compiler cannot hoist them past the stores)
    xi, yi, zi, r_i, m_i, a = grain_row(i, positions, radii, masses, materials)
    vxi = velocities[i, 0]
    vyi = velocities[i, 1]
    vzi = velocities[i, 2]
    wxi = angular_velocities[i, 0]
    wyi = angular_velocities[i, 1]
    wzi = angular_velocities[i, 2]
    fx = fy = fz = tx = ty = tz = 0.0
    for k in range(start[i], start[i + 1]):
        j = partners[k]
        touching, overlap, ratio, lever_i, lever_j, r_eff, m_eff, nx, ny, nz = pair_geometry(
            i, j, xi, yi, zi, r_i, m_i, positions, radii, masses, fixed, px, py, pz, lx, ly,
            lz)
        if not touching:
            dissipated_t += opened(model, params, a, materials[j], r_eff, history,
                                    pair_force, pair_torque_j, k)
            continue
        worst = max(worst, ratio)
        out = contact_response(
            model, params, a, materials[j], overlap, lever_i, lever_j, r_eff, m_eff, nx, ny,
            nz, vxi - velocities[j, 0], vyi - velocities[j, 1], vzi - velocities[j, 2],
            lever_i * wxi + lever_j * angular_velocities[j, 0],
            lever_i * wyi + lever_j * angular_velocities[j, 1],
            lever_i * wzi + lever_j * angular_velocities[j, 2],
            wxi - angular_velocities[j, 0], wyi - angular_velocities[j, 1],
            wzi - angular_velocities[j, 2], history, k, dt)
        for d in range(3):
            pair_force[k, d] = out[d]
            pair_torque_j[k, d] = out[6 + d]
        touch(history, k)
        fx += out[0]
        fy += out[1]
        fz += out[2]
        tx += out[3]
        ty += out[4]
        tz += out[5]
        dissipated_n += out[9]
        dissipated_t += out[10]
    own[i, 0] = fx
    own[i, 1] = fy
    own[i, 2] = fz
    own[i, 3] = tx
    own[i, 4] = ty
    own[i, 5] = tz
    max_overlap[i] = worst
    return dissipated_n, dissipated_t


@scalar
def stage_row(work, c, params, a, b):
    """Column c of the workspace given the pair-table row of materials a and b, unless
    it holds it already (row TABLE): in an oedometer of sand between steel walls nearly
    every contact has the row of the contact before it in that column, and copying the
    row (23 values) anyway cost 10 of the 60 us of the 280-grain bed's pair forces.
    With a single material the rows are filled once (law_loop.prepare)."""
    if params.shape[0] > 1:
        key = float(a * params.shape[0] + b)
        if work[TABLE * STRIDE + c] != key:
            for col in range(params.shape[2]):
                work[(PARAMS + col) * STRIDE + c] = params[a, b, col]
            work[TABLE * STRIDE + c] = key


@scalar
def stage_table(work, c, params, a, b, history, k):
    """Column c of the workspace: the pair-table row of materials a and b (stage_row)
    and the history of contact k."""
    stage_row(work, c, params, a, b)
    for h in range(history.shape[1]):
        work[(HISTORY + h) * STRIDE + c] = history[k, h]


@scalar
def _stage(work, c, params, a, b, history, k, overlap, lever_i, lever_j, r_eff, m_eff, nx, ny,
           nz, dvx, dvy, dvz, wx, wy, wz, dwx, dwy, dwz):
    """Column c of the workspace: the inputs of contact_response for wall contact k
    between materials a and b (law_loop.stage_geometry and v_rel), and
    stage_table."""
    stage_geometry(work, c, overlap, lever_i, lever_j, r_eff, m_eff, nx, ny, nz, wx, wy, wz,
                   dwx, dwy, dwz)
    work[DVX * STRIDE + c] = dvx
    work[(DVX + 1) * STRIDE + c] = dvy
    work[(DVX + 2) * STRIDE + c] = dvz
    stage_table(work, c, params, a, b, history, k)


@scalar
def _fill(count, work, slots, params, velocities, angular_velocities, radii, masses,
          materials, fixed, history):
    """Complete the pairs 0..count-1 gathered in ``work`` (their separations in rows
    SX..SZ, their pair, first and second grain in ``slots``) with what the law loop
    computes their geometry and law from: radii, masses, fixed flags, v_i - v_j, w_i,
    w_j, pair-table row and history.  The history is copied in a loop of its own, and
    the slot rows are read as 1-D views (7.0 -> 6.2 ns per contact, 280-grain bed)."""
    pairs = slots[0]
    first = slots[1]
    second = slots[2]
    for c in range(count):
        i = first[c]
        j = second[c]
        work[R_I * STRIDE + c] = radii[i]
        work[R_J * STRIDE + c] = radii[j]
        work[M_I * STRIDE + c] = masses[i]
        work[M_J * STRIDE + c] = masses[j]
        work[FIXED_I * STRIDE + c] = fixed[i]
        work[FIXED_J * STRIDE + c] = fixed[j]
        work[DVX * STRIDE + c] = velocities[i, 0] - velocities[j, 0]
        work[(DVX + 1) * STRIDE + c] = velocities[i, 1] - velocities[j, 1]
        work[(DVX + 2) * STRIDE + c] = velocities[i, 2] - velocities[j, 2]
        work[W_I * STRIDE + c] = angular_velocities[i, 0]
        work[(W_I + 1) * STRIDE + c] = angular_velocities[i, 1]
        work[(W_I + 2) * STRIDE + c] = angular_velocities[i, 2]
        work[W_J * STRIDE + c] = angular_velocities[j, 0]
        work[(W_J + 1) * STRIDE + c] = angular_velocities[j, 1]
        work[(W_J + 2) * STRIDE + c] = angular_velocities[j, 2]
    if params.shape[0] > 1:
        for c in range(count):
            stage_row(work, c, params, materials[first[c]], materials[second[c]])
    for h in range(history.shape[1]):
        for c in range(count):
            work[(HISTORY + h) * STRIDE + c] = history[pairs[c], h]


@scalar
def whole_lanes(count):
    """``count`` rounded up to whole SIMD vectors of 8 doubles (CAP is a multiple of 8):
    the law loop's scalar remainder costs about 40 ns per contact, a vector of 8 about
    50 ns.  The columns beyond count hold earlier contacts' numbers (or zeros); what the
    law writes there is never read."""
    return (count + 7) // 8 * 8


@scalar
def _flush(law, work, count, slots, hi, params, velocities, angular_velocities, radii, masses,
           materials, fixed, history, pair_force, own, pair_torque_j, dt):
    """Complete the ``count`` contacts gathered in ``work`` (_fill), evaluate their law
    (law_loop.py) and scatter them back in gathering order: forces, histories, and the
    sums on each grain of the block (grains below ``hi``); the torque on a second grain
    beyond the block is stored for the gather.  Returns the normal and
    tangential energy dissipated [J], their largest overlap / smaller radius and how
    many of them start (touch: collisions)."""
    _fill(count, work, slots, params, velocities, angular_velocities, radii, masses,
          materials, fixed, history)
    call_law(law, work, whole_lanes(count), dt, np.int64(1))
    lost_n = 0.0
    lost_t = 0.0
    worst = 0.0
    started = 0
    for s in range(count):
        k = slots[0, s]
        i = slots[1, s]
        j = slots[2, s]
        inside = j < hi
        worst = max(worst, work[RATIO * STRIDE + s])
        for d in range(3):
            f = work[(OUTPUT + d) * STRIDE + s]
            pair_force[k, d] = f
            own[i, d] += f
            if inside:
                own[j, d] -= f
        for d in range(3):
            torque_j = work[(OUTPUT + 6 + d) * STRIDE + s]
            own[i, 3 + d] += work[(OUTPUT + 3 + d) * STRIDE + s]
            if inside:
                own[j, 3 + d] += torque_j
            else:
                pair_torque_j[k, d] = torque_j
        for h in range(history.shape[1]):
            history[k, h] = work[(HISTORY + h) * STRIDE + s]
        started += touch(history, k)
        lost_n += work[(OUTPUT + 9) * STRIDE + s]
        lost_t += work[(OUTPUT + 10) * STRIDE + s]
    return lost_n, lost_t, worst, started


@block
def _pair_block(lo, hi, law, walk, work, slots, dirty, model, params, positions, velocities,
                angular_velocities, radii, masses, materials, fixed, periodic_flag,
                periodic_length, start, partners, owner, history, pair_force, own,
                pair_torque_j, max_overlap, dt):
    """The pairs listed by grains lo..hi-1: in 3D batched through the law loop at
    ``law`` (_pair_rows); for 2D disks by the pair walk compiled for the model at
    ``walk`` (planar.py, non-zero), which leaves its energies and collisions in the
    block's workspace ``work[0:3]``."""
    if walk != 0:
        call_walk(walk, lo, hi, dt, work, dirty, params, positions, velocities,
                  angular_velocities, radii, masses, materials, fixed, periodic_flag,
                  periodic_length, start, partners, owner, history, pair_force, own,
                  pair_torque_j, max_overlap)
        return work[0], work[1], np.int64(work[2])
    return _pair_rows(lo, hi, law, work, slots, dirty, model, params, positions, velocities,
                      angular_velocities, radii, masses, materials, fixed, periodic_flag,
                      periodic_length, start, partners, owner, history, pair_force, own,
                      pair_torque_j, max_overlap, dt)


@scalar
def clear_own(lo, hi, own):
    """Zero the force and torque sums own[i] (6) of grains lo..hi-1 before a block's
    pair walk adds to them."""
    for i in range(lo, hi):
        for d in range(6):
            own[i, d] = 0.0


@scalar
def walk_pair(k, owner, partners, positions, radii, masses, materials, px, py, pz, lx, ly,
              lz):
    """Listed pair k of a block's walk: its grains i = owner[k] and j, i's material,
    the radii, i's mass, the separation r_i - r_j (3) [m] (the minimum image along
    periodic directions px, py, pz of lengths lx, ly, lz), R_i + R_j [m] and whether
    the two touch."""
    i = owner[k]
    j = partners[k]
    xi, yi, zi, r_i, m_i, a = grain_row(i, positions, radii, masses, materials)
    dx, dy, dz = separation(j, xi, yi, zi, positions, px, py, pz, lx, ly, lz)
    r_j = radii[j]
    rsum = r_i + r_j
    return i, j, a, r_i, r_j, m_i, dx, dy, dz, rsum, dx * dx + dy * dy + dz * dz < rsum * rsum


@block_body
def _pair_rows(lo, hi, law, work, slots, dirty, model, params, positions, velocities,
               angular_velocities, radii, masses, materials, fixed, periodic_flag,
               periodic_length, start, partners, owner, history, pair_force, own,
               pair_torque_j, max_overlap, dt):
    """The pairs listed by grains lo..hi-1: the touching ones gathered CAP at a time
    into ``work`` and evaluated by the law loop (_flush); returns the energies and the
    number of pairs that start (collisions).  Same pair forces as pair_row, to the bit.
    The gathering has no branch on the contact test (every pair is written at the next
    free column, which advances only when it touches): that branch, taken or not at
    random, cost more than the rest of the gathering.  The pairs are walked in one loop
    over k, each reading its first grain from ``owner`` (neighbors.list_owners): a
    loop per grain, over its two or three pairs, mispredicted its exit at every
    grain (pair block of the 280-grain bed 13.85 -> 13.25 us).  dirty[k] = 0 says that pair k's
    force, torque and history are zero (it was open at the last evaluation), so an open
    pair is not read again."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    px, py, pz = periodic_flag[0], periodic_flag[1], periodic_flag[2]
    lx, ly, lz = periodic_length[0], periodic_length[1], periodic_length[2]
    count = 0
    worst = 0.0
    started = 0
    clear_own(lo, hi, own)
    for k in range(start[lo], start[hi]):
        i, j, a, r_i, r_j, m_i, dx, dy, dz, rsum, touching = walk_pair(
            k, owner, partners, positions, radii, masses, materials, px, py, pz, lx, ly, lz)
        if dirty[k] > int(touching):     # open, and perhaps not cleared yet
            dissipated_t += opened(model, params, a, materials[j], r_i * r_j / rsum,
                                    history, pair_force, pair_torque_j, k)
        dirty[k] = touching
        work[SX * STRIDE + count] = dx
        work[SY * STRIDE + count] = dy
        work[SZ * STRIDE + count] = dz
        slots[0, count] = k
        slots[1, count] = i
        slots[2, count] = j
        count += touching
        if count == CAP:
            dn, dt_, deepest, new = _flush(law, work, count, slots, hi, params, velocities,
                                           angular_velocities, radii, masses, materials,
                                           fixed, history, pair_force, own, pair_torque_j,
                                           dt)
            dissipated_n += dn
            dissipated_t += dt_
            worst = max(worst, deepest)
            started += new
            count = 0
    if count > 0:
        dn, dt_, deepest, new = _flush(law, work, count, slots, hi, params, velocities,
                                       angular_velocities, radii, masses, materials, fixed,
                                       history, pair_force, own, pair_torque_j, dt)
        dissipated_n += dn
        dissipated_t += dt_
        worst = max(worst, deepest)
        started += new
    keep_worst(lo, hi, worst, max_overlap)
    return dissipated_n, dissipated_t, started


@scalar
def largest(values):
    """The largest of ``values`` (1-D), 0 for none or all negative (ndarray.max
    allocates a temporary: not in code compiled without reference counting)."""
    top = 0.0
    for i in range(values.size):
        top = max(top, values[i])
    return top


@scalar
def keep_worst(lo, hi, worst, max_overlap):
    """Raise max_overlap[lo] to ``worst``, the largest overlap / smaller radius of the
    contacts of grains lo..hi-1: the CPU keeps it by block (at its first grain), as the
    loop reads only its maximum (loop._checks), so that no contact reads and writes the
    array (the GPU, pair_row and wall_row, keep it by grain)."""
    if hi > lo:
        max_overlap[lo] = max(max_overlap[lo], worst)


@scalar
def wall_gap(i, q, model, params, positions, radii, materials, wall_kind, wall_geometry,
             wall_offset, wall_material, wall_ids, wall_history, wall_force, wall_torque):
    """Wall contact q of grain i: (overlap [m], unit normal (3) from the wall to the
    grain, energy [J] lost with the history of a contact found open: overlap <= 0, whose
    rows are then zeroed, _release; the wall w and the lever R_i - overlap [m])."""
    w = wall_ids[q]
    dist, nx, ny, nz = wall_distance(wall_kind, wall_geometry, wall_offset, w,
                                     positions[i, 0], positions[i, 1], positions[i, 2])
    overlap = radii[i] - dist
    lost = 0.0
    if overlap <= 0.0:
        lost = _release(model, params, materials[i], wall_material[w], radii[i], wall_history,
                        wall_force, wall_torque, q)
    return overlap, nx, ny, nz, lost, w, radii[i] - overlap


@scalar
def wall_row(i, model, params, positions, velocities, angular_velocities, radii, masses,
             materials, wall_kind, wall_geometry, wall_offset, wall_velocity, wall_material,
             wall_start, wall_ids, wall_history, wall_force, wall_torque, max_overlap, dt):
    """The wall contacts of grain i, one after the other (the GPU kernels' loop body;
    the CPU batches them, _wall_block): writes their forces, torques, touching marks
    (touch) and max_overlap[i]; returns the normal and tangential energy dissipated
    [J]."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    worst = max_overlap[i]
    r_i = radii[i]
    for q in range(wall_start[i], wall_start[i + 1]):
        overlap, nx, ny, nz, lost, w, lever = wall_gap(
            i, q, model, params, positions, radii, materials, wall_kind, wall_geometry,
            wall_offset, wall_material, wall_ids, wall_history, wall_force, wall_torque)
        if overlap <= 0.0:
            dissipated_t += lost
            continue
        worst = max(worst, overlap / r_i)
        out = contact_response(
            model, params, materials[i], wall_material[w], overlap, lever, 0.0, r_i,
            masses[i], nx, ny, nz,
            velocities[i, 0] - wall_velocity[w, 0], velocities[i, 1] - wall_velocity[w, 1],
            velocities[i, 2] - wall_velocity[w, 2],
            lever * angular_velocities[i, 0], lever * angular_velocities[i, 1],
            lever * angular_velocities[i, 2], angular_velocities[i, 0],
            angular_velocities[i, 1], angular_velocities[i, 2], wall_history, q, dt)
        for d in range(3):
            wall_force[q, d] = out[d]
            wall_torque[q, d] = out[3 + d]
        touch(wall_history, q)
        dissipated_n += out[9]
        dissipated_t += out[10]
    max_overlap[i] = worst
    return dissipated_n, dissipated_t


@scalar
def store_lanes(work, count, slots, history, force, torque, own, share):
    """Put the law's outputs for the ``count`` contacts of ``work`` where they belong:
    the force and torque of contact slots[0, s] into ``force``/``torque`` and added to
    own of its grain slots[1, s], its history back into ``history``.  Returns ``share``
    times the normal and tangential energy they dissipated [J] (1 for walls, 1/2 for
    the image contacts each grain of a mirrored pair counts), their largest overlap /
    smaller radius (RATIO) and how many of them start (touch)."""
    lost_n = 0.0
    lost_t = 0.0
    worst = 0.0
    started = 0
    for s in range(count):
        q = slots[0, s]
        i = slots[1, s]
        worst = max(worst, work[RATIO * STRIDE + s])
        for d in range(3):
            f = work[(OUTPUT + d) * STRIDE + s]
            t = work[(OUTPUT + 3 + d) * STRIDE + s]
            force[q, d] = f
            torque[q, d] = t
            own[i, d] += f
            own[i, 3 + d] += t
        for h in range(history.shape[1]):
            history[q, h] = work[(HISTORY + h) * STRIDE + s]
        started += touch(history, q)
        lost_n += share * work[(OUTPUT + 9) * STRIDE + s]
        lost_t += share * work[(OUTPUT + 10) * STRIDE + s]
    return lost_n, lost_t, worst, started


@scalar
def _flush_walls(law, work, count, slots, wall_history, wall_force, wall_torque, own, dt):
    """Evaluate the law on the ``count`` wall contacts gathered in ``work``, store
    their forces, torques and histories and add them to own (their grains are in the
    block, slots[1]); returns the normal and tangential energy dissipated [J] and how
    many of them start (touch: collisions)."""
    call_law(law, work, whole_lanes(count), dt, np.int64(0))
    lost_n, lost_t, _, started = store_lanes(work, count, slots, wall_history, wall_force,
                                             wall_torque, own, 1.0)
    return lost_n, lost_t, started


@block
def _wall_block(lo, hi, law, work, slots, model, params, positions, velocities,
                angular_velocities, radii, masses, materials, wall_kind, wall_geometry,
                wall_offset, wall_velocity, wall_material, wall_start, wall_ids, wall_owner,
                wall_history, wall_force, wall_torque, own, max_overlap, dt):
    """The wall contacts of grains lo..hi-1 (as wall_row, to the bit): the touching ones
    gathered CAP at a time into ``work`` and evaluated by the law loop, and added to
    own; returns the energies and the number of contacts that start (collisions).  One
    loop over the candidates q, their grains read from ``wall_owner`` (as the pair walk,
    _pair_block)."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    count = 0
    worst = 0.0
    started = 0
    for q in range(wall_start[lo], wall_start[hi]):
        i = wall_owner[q]
        r_i = radii[i]
        overlap, nx, ny, nz, lost, w, lever = wall_gap(
            i, q, model, params, positions, radii, materials, wall_kind, wall_geometry,
            wall_offset, wall_material, wall_ids, wall_history, wall_force, wall_torque)
        if overlap <= 0.0:
            dissipated_t += lost
            continue
        worst = max(worst, overlap / r_i)
        _stage(work, count, params, materials[i], wall_material[w], wall_history, q,
               overlap, lever, 0.0, r_i, masses[i], nx, ny, nz,
               velocities[i, 0] - wall_velocity[w, 0],
               velocities[i, 1] - wall_velocity[w, 1],
               velocities[i, 2] - wall_velocity[w, 2], lever * angular_velocities[i, 0],
               lever * angular_velocities[i, 1], lever * angular_velocities[i, 2],
               angular_velocities[i, 0], angular_velocities[i, 1],
               angular_velocities[i, 2])
        slots[0, count] = q
        slots[1, count] = i
        count += 1
        if count == CAP:
            dn, dt_, new = _flush_walls(law, work, count, slots, wall_history, wall_force,
                                        wall_torque, own, dt)
            dissipated_n += dn
            dissipated_t += dt_
            started += new
            count = 0
    if count > 0:
        dn, dt_, new = _flush_walls(law, work, count, slots, wall_history, wall_force,
                                    wall_torque, own, dt)
        dissipated_n += dn
        dissipated_t += dt_
        started += new
    keep_worst(lo, hi, worst, max_overlap)
    return dissipated_n, dissipated_t, started


PAIRS = 1     # contact_forces' parts: the listed pairs, the wall contacts, or both,
WALLS = 2     # and PLANAR for a 2D system (its pairs by the walk at law.planar, _pair_block)
PLANAR = 4


@block
def _contact_block(lo, hi, parts, law, walk, work, slots, dirty, model, params, positions,
                   velocities, angular_velocities, radii, masses, materials, fixed,
                   periodic_flag, periodic_length, start, partners, owner, history,
                   pair_force, pair_torque_j, wall_kind, wall_geometry, wall_offset, wall_velocity,
                   wall_material, wall_start, wall_ids, wall_owner, wall_history, wall_force,
                   wall_torque, own, max_overlap, dt):
    """The pairs (_pair_block: by the law loop at ``law``, or the 2D pair walk at
    ``walk`` when non-zero) then the wall contacts (_wall_block) of grains lo..hi-1, as
    ``parts`` says; returns the energies and the grain-pair and grain-wall
    collisions."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    pair_collisions = 0
    wall_collisions = 0
    if parts & PAIRS:
        dissipated_n, dissipated_t, pair_collisions = _pair_block(
            lo, hi, law, walk, work, slots, dirty, model, params, positions, velocities,
            angular_velocities, radii, masses, materials, fixed, periodic_flag,
            periodic_length, start, partners, owner, history, pair_force, own,
            pair_torque_j, max_overlap, dt)
    if parts & WALLS:
        wn, wt, wall_collisions = _wall_block(
            lo, hi, law, work, slots, model, params, positions, velocities,
            angular_velocities, radii, masses, materials, wall_kind, wall_geometry,
            wall_offset, wall_velocity, wall_material, wall_start, wall_ids, wall_owner,
            wall_history, wall_force, wall_torque, own, max_overlap, dt)
        dissipated_n += wn
        dissipated_t += wt
    return dissipated_n, dissipated_t, pair_collisions, wall_collisions


@parallel
def contact_forces(model, params, law, positions, velocities, angular_velocities, radii,
                   masses, materials, fixed, periodic_flag, periodic_length, start, partners,
                   owner, history, pair_force, pair_torque_j, wall_kind, wall_geometry,
                   wall_offset, wall_velocity, wall_material, wall_start, wall_ids, wall_owner,
                   wall_history, wall_force, wall_torque, own, max_overlap, dt, nblock, parts):
    """Forces of every listed pair (zero, and history reset, for pairs not touching) and
    of the walls on grains (per grain-wall candidate, R_j = infinity), each block of
    grains in one parallel region: its pairs, then its wall contacts.

    owner[k], wall_owner[q] : the grain of pair k that lists it, of wall candidate q
    (neighbors.list_owners).
    law : bundles.LawWorkspace (law_loop.workspace): the address of the law loop
    (law_loop.law_address) and of the 2D pair walk (planar.planar_address), workspaces (nblock, ...), slots (nblock, 3, CAP), dirty
    (one byte per pair slot), energies (nblock, 2), collisions (nblock, 2).
    pair_force[k] [N] is the force on the first grain i of pair k and pair_torque_j[k]
    [N m] the torque on its second grain j when j is in another block; own[i] (6) is
    the sum of the forces and torques on i of the pairs it lists, of the pairs of its
    block that list it, in gathering order, then of its wall contacts.
    max_overlap keeps the largest overlap / min(R_i, R_j) (R_i against a wall) since the
    loop last read and reset it (keep_worst: by block on the CPU, by grain on the GPU).
    parts : PAIRS | WALLS for a step; PAIRS alone (which zeroes own first) or WALLS alone
    (which adds to own) time or test one kind; | PLANAR in 2D (the pairs by the walk
    at law.planar).
    Returns the energies dissipated in the step, normal and tangential [J], and the
    grain-pair and grain-wall contacts that start in it (collisions: touch), summed
    over ``nblock`` fixed blocks of grains (block_count) in block order.
    """
    n = positions.shape[0]
    address, work, slots, dirty, sums, started = \
        law.address, law.work, law.slots, law.dirty, law.sums, law.collisions
    walk = law.planar if parts & PLANAR else 0
    if nblock == 1:    # no parallel region to enter (a few us per call); a plain int64 0
        return _contact_block(
            np.int64(0), n, parts, address, walk, work[0], slots[0], dirty, model, params,
            positions, velocities, angular_velocities, radii, masses, materials, fixed,
            periodic_flag, periodic_length, start, partners, owner, history, pair_force,
            pair_torque_j, wall_kind, wall_geometry, wall_offset, wall_velocity,
            wall_material, wall_start, wall_ids, wall_owner, wall_history, wall_force, wall_torque,
            own, max_overlap, dt)
    for b in prange(nblock):
        sums[b, 0], sums[b, 1], started[b, 0], started[b, 1] = _contact_block(
            b * n // nblock, (b + 1) * n // nblock, parts, address, walk, work[b], slots[b],
            dirty,
            model, params, positions, velocities, angular_velocities, radii, masses,
            materials, fixed, periodic_flag, periodic_length, start, partners, owner,
            history, pair_force, pair_torque_j, wall_kind, wall_geometry, wall_offset,
            wall_velocity, wall_material, wall_start, wall_ids, wall_owner, wall_history,
            wall_force, wall_torque, own, max_overlap, dt)
    return block_total(sums, started, nblock)


def block_count(n, threads):
    """Number of fixed blocks of grains the passes hand to threads: one per thread at
    least, about 2048 grains each, at most two per thread and MAX_BLOCKS.  More blocks
    let a thread that runs ahead take another (the 10 000-grain bed on 2 threads, in a
    phase where one thread was slow: 0.97-1.04 s in 4 blocks, 1.27-1.33 s in 2), but
    cut more pairs across blocks, whose forces the gather must read back (1e5 grains
    on 2 threads, 500 steps: 3.42-3.48 s in 4 blocks, 3.8-5.0 s in 48).  A single
    block on one thread (no parallel region is entered, and every pair is added to
    both its grains as it is computed) and below SERIAL grains per thread, where a
    step is a few microseconds and entering a parallel region (about 2 us) costs more
    than it saves: the 280-grain bed in two blocks on two threads took 0.40-0.41 s
    against 0.45-0.47 s in one, but 0.80-0.82 s at another time of the same day
    (cause not found).  The blocks depend only on n and the
    thread count, so sums over them are the same from run to run."""
    if threads == 1 or n < SERIAL * threads:
        return 1
    return min(MAX_BLOCKS, max(threads, min(2 * threads, n // 2048)))


@scalar
def block_total(sums, started, nblock):
    """Column sums of the energies and the collisions of the first ``nblock`` blocks,
    in block order."""
    total_n = 0.0
    total_t = 0.0
    pair_collisions = 0
    wall_collisions = 0
    for b in range(nblock):
        total_n += sums[b, 0]
        total_t += sums[b, 1]
        pair_collisions += started[b, 0]
        wall_collisions += started[b, 1]
    return total_n, total_t, pair_collisions, wall_collisions


@scalar
def _add_contact(fx, fy, fz, tx, ty, tz, force, sign, torque, k):
    """The running force and torque sums plus sign * force[k] and torque[k]."""
    return (fx + sign * force[k, 0], fy + sign * force[k, 1], fz + sign * force[k, 2],
            tx + torque[k, 0], ty + torque[k, 1], tz + torque[k, 2])


@scalar
def gather_pairs(i, mass, gravity, own, reverse_start, reverse_pairs, owned_from, pair_force,
                 pair_torque_j):
    """Force [N] and torque [N m] on grain i from m_i g, own[i] and, one by one, the
    pairs k < owned_from that list it (those from k = owned_from on are already in
    own[i]), in this order.  The CPU's gather: own[i] holds the grain's wall contacts
    too (_wall_block)."""
    fx = mass * gravity[0] + own[i, 0]
    fy = mass * gravity[1] + own[i, 1]
    fz = mass * gravity[2] + own[i, 2]
    tx = own[i, 3]
    ty = own[i, 4]
    tz = own[i, 5]
    if owned_from > 0:       # else no pair can be below it: the first block on the CPU
        for s in range(reverse_start[i], reverse_start[i + 1]):
            k = reverse_pairs[s]
            if k >= owned_from:                # listed in k order (neighbors._reverse)
                break
            fx, fy, fz, tx, ty, tz = _add_contact(fx, fy, fz, tx, ty, tz, pair_force, -1.0,
                                                  pair_torque_j, k)
    return fx, fy, fz, tx, ty, tz


@scalar
def gather_grain(i, mass, gravity, own, reverse_start, reverse_pairs, owned_from,
                 pair_force, pair_torque_j, wall_start, wall_force, wall_torque):
    """Force [N] and torque [N m] on grain i: gather_pairs, then its wall contacts one
    by one (the GPU's gather: its own[i] holds only the pairs i lists)."""
    fx, fy, fz, tx, ty, tz = gather_pairs(i, mass, gravity, own, reverse_start,
                                          reverse_pairs, owned_from, pair_force,
                                          pair_torque_j)
    for q in range(wall_start[i], wall_start[i + 1]):
        fx, fy, fz, tx, ty, tz = _add_contact(fx, fy, fz, tx, ty, tz, wall_force, 1.0,
                                              wall_torque, q)
    return fx, fy, fz, tx, ty, tz
