"""2D pairs: the walk over the pairs of disks, compiled for each contact model.

In 2D the law is short (the springs' scalar form, physics/tangential.py) and staging
it for SIMD lanes (law_loop) cost more than the lanes saved (BENCHMARKS.md, the 2D
silo), so each touching pair's law is evaluated as the walk meets it (_planar_rows).
Through physics.contact.contact_force with the model ids read at run time, the walk
spent more than a third of its time in choosing among every law and in what that
generality keeps alive (the 2000-disk silo bed: 76.6 us a step against 48.9 us for the
same law written into the walk, BENCHMARKS.md).  So the walk is compiled once per
model composition, as law_loop compiles the law loop: a copy of contact_force with
the model ids made constants and the branches they decide pruned
(law_loop.specialized), in a C callback (``_walk``) reached through its address
(law_loop.call_walk, contacts._pair_block), so that changing the law never recompiles
the time loop.  Its forces are those of the generic walk, to the bit.
"""
import numpy as np
from numba import carray

from ..._jit import block, block_body, callback, kernel, retarget, scalar
from ...physics.contact import contact_force
from .contacts import clear_own, keep_worst, opened, touch, walk_pair
from .law_loop import WALK_SIGNATURE, specialized
from .response import contact_geometry, planar_response

_WALKS = {}


@block
def _opened_pair(model, params, a, b, r_eff, history, pair_force, pair_torque_j, k):
    """``opened`` compiled apart, for a loop that calls it rarely and whose registers
    its inlined body would take."""
    return opened(model, params, a, b, r_eff, history, pair_force, pair_torque_j, k)


@block_body
def _planar_rows(lo, hi, dirty, model, params, positions, velocities, angular_velocities,
                 radii, masses, materials, fixed, periodic_flag, periodic_length, start,
                 partners, owner, history, pair_force, own, pair_torque_j, max_overlap, dt):
    """The pairs listed by 2D disks lo..hi-1, each touching pair's law evaluated as it
    is met (response.planar_response) and its force and torque added to its grains at
    once: what contacts._pair_rows computes, in the same order, without the workspace.
    The pairs are walked as _pair_rows walks them, in one loop over k (a loop per
    grain was slower here too).  Writes own, pair_force (and pair_torque_j for a second
    grain beyond the block), histories and touching marks; returns the energies and
    the number of pairs that start (collisions)."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    worst = 0.0
    started = 0
    px, py, pz = periodic_flag[0], periodic_flag[1], periodic_flag[2]
    lx, ly, lz = periodic_length[0], periodic_length[1], periodic_length[2]
    clear_own(lo, hi, own)
    for k in range(start[lo], start[hi]):
        i, j, a, r_i, r_j, m_i, dx, dy, dz, rsum, touching = walk_pair(
            k, owner, partners, positions, radii, masses, materials, px, py, pz, lx, ly, lz)
        if dirty[k] != touching:        # a contact that starts, or one that opened
            if not touching:
                dissipated_t += _opened_pair(model, params, a, materials[j],
                                             r_i * r_j / rsum, history, pair_force,
                                             pair_torque_j, k)
            dirty[k] = touching
        if not touching:
            continue
        overlap, ratio, lever_i, lever_j, r_eff, m_eff, nx, ny, nz = contact_geometry(
            dx, dy, 0.0, r_i, r_j, m_i, masses[j], fixed[i], fixed[j])
        worst = max(worst, ratio)
        wi = angular_velocities[i, 2]
        wj = angular_velocities[j, 2]
        fx, fy, torque_i, torque_j, dn, dt_ = planar_response(
            model, params, a, materials[j], overlap, lever_i, lever_j, r_eff, m_eff, nx, ny,
            velocities[i, 0] - velocities[j, 0], velocities[i, 1] - velocities[j, 1],
            lever_i * wi + lever_j * wj, wi - wj, history, k, dt)
        pair_force[k, 0] = fx
        pair_force[k, 1] = fy
        own[i, 0] += fx
        own[i, 1] += fy
        own[i, 5] += torque_i
        if j < hi:
            own[j, 0] -= fx
            own[j, 1] -= fy
            own[j, 5] += torque_j
        else:
            pair_torque_j[k, 2] = torque_j
        started += touch(history, k)
        dissipated_n += dn
        dissipated_t += dt_
    keep_worst(lo, hi, worst, max_overlap)
    return dissipated_n, dissipated_t, started


def _walk(lo, hi, dt, n, slots, columns, materials_count, table_columns, p_work, p_dirty,
          p_params, p_positions, p_velocities, p_angular_velocities, p_radii, p_masses,
          p_materials, p_fixed, p_periodic_flag, p_periodic_length, p_start, p_partners,
          p_owner, p_history, p_pair_force, p_own, p_pair_torque_j, p_max_overlap):
    """The C callback of law_loop.WALK_SIGNATURE (template: MODEL and planar_rows are
    set in each compiled copy, planar_address): the arrays rebuilt from their data and
    sizes, _planar_rows run on grains lo..hi-1 and its energies and collisions left in
    work[0:3]."""
    work = carray(p_work, (3,), np.float64)
    dirty = carray(p_dirty, (slots,), np.uint8)
    params = carray(p_params, (materials_count, materials_count, table_columns), np.float64)
    positions = carray(p_positions, (n, 3), np.float64)
    velocities = carray(p_velocities, (n, 3), np.float64)
    angular_velocities = carray(p_angular_velocities, (n, 3), np.float64)
    radii = carray(p_radii, (n,), np.float64)
    masses = carray(p_masses, (n,), np.float64)
    materials = carray(p_materials, (n,), np.int32)
    fixed = carray(p_fixed, (n,), np.int8)
    periodic_flag = carray(p_periodic_flag, (3,), np.int64)
    periodic_length = carray(p_periodic_length, (3,), np.float64)
    start = carray(p_start, (n + 1,), np.int64)
    partners = carray(p_partners, (slots,), np.uint32)
    owner = carray(p_owner, (slots,), np.uint32)
    history = carray(p_history, (slots, columns), np.float64)
    pair_force = carray(p_pair_force, (slots, 3), np.float64)
    own = carray(p_own, (n, 6), np.float64)
    pair_torque_j = carray(p_pair_torque_j, (slots, 3), np.float64)
    max_overlap = carray(p_max_overlap, (n,), np.float64)
    lost_n, lost_t, started = planar_rows(  # noqa: F821 (set by planar_address)
        lo, hi, dirty, MODEL, params, positions, velocities,  # noqa: F821
        angular_velocities, radii, masses, materials, fixed, periodic_flag,
        periodic_length, start, partners, owner, history, pair_force, own, pair_torque_j,
        max_overlap, dt)
    work[0] = lost_n
    work[1] = lost_t
    work[2] = started


def planar_address(model_ids):
    """Address of the 2D pair walk compiled for the model ``model_ids``
    (ContactModel.ids(2)), compiled on its first use and then cached on disk."""
    key = tuple(int(x) for x in model_ids)
    if key not in _WALKS:
        suffix = "_planar_" + "_".join(str(x) for x in key)
        memo = {}
        memo[contact_force] = specialized(contact_force, key, scalar, memo, {}, suffix)
        rows = retarget(_planar_rows, scalar, memo, {"_opened_pair": _opened_pair}, suffix)
        _WALKS[key] = retarget(kernel(_walk), callback(WALK_SIGNATURE), {},
                               {"MODEL": key, "planar_rows": rows}, suffix)
    return _WALKS[key].address
