"""Contact forces between grains and the mirror images the symmetry planes make of the
grains near them (core/symmetry.py states the geometry and what it reproduces).

Image candidate q of grain i is the pair (i, j') with j' the image of grain j through
the planes of its mask: the law of two grains (physics.contact_force through the law
loop, in pair mode) evaluated from r_i - r_j', v_i - M v_j, w_i and det(M) M w_j, with
the contact's own history.  Only grain i feels it: the image is not a grain, and the
same contact seen from j (j, i') is j's own candidate, so each force is written to one
grain and the blocks stay independent.  The force and torque on i are stored per
candidate (``Images.force``, ``torque``: what the contact reports read) and added to
own[i] after the pairs and walls of the evaluation (contacts.contact_forces), so the
gather takes them with the rest.

Energies: a contact with an image is shared with the mirror half of the system, so
each candidate counts half the energy it dissipates (and half its elastic energy,
energy.elastic_energy): then the kinetic, gravitational and elastic energy of the
grains plus the dissipation is conserved as in the full system, (i, j') and (j, i')
together counting one contact, and a grain's contact with its own image (i, i'),
listed once, half of one.  Every image contact that starts counts as a grain-pair
collision of its grain.
"""
import numpy as np

from ..._jit import block, parallel, prange, scalar
from ...core.symmetry import MASKS, image_separation, mirror_sign, spin_sign
from .contacts import block_total, keep_worst, opened, stage_table, store_lanes, whole_lanes
from .law_loop import (CAP, DVX, FIXED_I, FIXED_J, M_I, M_J, R_I, R_J, STRIDE, SX, SY, SZ,
                       W_I, W_J, call_law)


@scalar
def _fill_images(count, work, slots, params, velocities, angular_velocities, radii, masses,
                 materials, fixed, history):
    """Complete the image contacts 0..count-1 gathered in ``work`` (separations in SX..SZ;
    candidate, grain and image code in ``slots``): the radii, masses, fixed flags,
    v_i - M v_j, w_i, det(M) M w_j, pair-table row and history the law loop reads."""
    for c in range(count):
        i = slots[1, c]
        code = slots[2, c]
        j = code // MASKS
        mask = code % MASKS
        work[R_I * STRIDE + c] = radii[i]
        work[R_J * STRIDE + c] = radii[j]
        work[M_I * STRIDE + c] = masses[i]
        work[M_J * STRIDE + c] = masses[j]
        work[FIXED_I * STRIDE + c] = fixed[i]
        work[FIXED_J * STRIDE + c] = fixed[j]
        for d in range(3):
            work[(DVX + d) * STRIDE + c] = velocities[i, d] \
                - mirror_sign(d, mask) * velocities[j, d]
            work[(W_I + d) * STRIDE + c] = angular_velocities[i, d]
            work[(W_J + d) * STRIDE + c] = spin_sign(d, mask) * angular_velocities[j, d]
        stage_table(work, c, params, materials[i], materials[j], history, slots[0, c])


@scalar
def _flush_images(law, work, count, slots, params, velocities, angular_velocities, radii,
                  masses, materials, fixed, history, force, torque, own, dt):
    """Evaluate the law on the ``count`` image contacts gathered in ``work``, store their
    force and torque on their grain and their histories, and add them to own; returns
    half the normal and tangential energy they dissipate [J] (module docstring), their
    largest overlap / smaller radius and how many of them start (touch)."""
    _fill_images(count, work, slots, params, velocities, angular_velocities, radii, masses,
                 materials, fixed, history)
    call_law(law, work, whole_lanes(count), dt, np.int64(1))
    return store_lanes(work, count, slots, history, force, torque, own, 0.5)


@block
def _image_block(lo, hi, law, work, slots, model, params, positions, velocities,
                 angular_velocities, radii, masses, materials, fixed, periodic_flag,
                 periodic_length, at, start, codes, owner, history, force, torque, own,
                 max_overlap, dt):
    """The image candidates of grains lo..hi-1: the touching ones gathered CAP at a time
    and evaluated by the law loop (_flush_images), the others' rows cleared when they
    open (contacts.opened: half of the energy their springs held is lost).  Returns the
    energies and the contacts that start."""
    dissipated_n = 0.0
    dissipated_t = 0.0
    count = 0
    worst = 0.0
    started = 0
    for q in range(start[lo], start[hi]):
        i = owner[q]
        code = codes[q]
        j = code // MASKS
        dx, dy, dz = image_separation(i, code, positions, at, periodic_flag, periodic_length)
        rsum = radii[i] + radii[j]
        if dx * dx + dy * dy + dz * dz >= rsum * rsum:
            dissipated_t += 0.5 * opened(model, params, materials[i], materials[j],
                                         radii[i] * radii[j] / rsum, history, force, torque, q)
            continue
        work[SX * STRIDE + count] = dx
        work[SY * STRIDE + count] = dy
        work[SZ * STRIDE + count] = dz
        slots[0, count] = q
        slots[1, count] = i
        slots[2, count] = code
        count += 1
        if count == CAP:
            dn, dt_, deepest, new = _flush_images(law, work, count, slots, params, velocities,
                                                  angular_velocities, radii, masses, materials,
                                                  fixed, history, force, torque, own, dt)
            dissipated_n += dn
            dissipated_t += dt_
            worst = max(worst, deepest)
            started += new
            count = 0
    if count > 0:
        dn, dt_, deepest, new = _flush_images(law, work, count, slots, params, velocities,
                                              angular_velocities, radii, masses, materials,
                                              fixed, history, force, torque, own, dt)
        dissipated_n += dn
        dissipated_t += dt_
        worst = max(worst, deepest)
        started += new
    keep_worst(lo, hi, worst, max_overlap)
    return dissipated_n, dissipated_t, started


@parallel
def image_forces(model, params, law, positions, velocities, angular_velocities, radii, masses,
                 materials, fixed, periodic_flag, periodic_length, at, start, codes, owner,
                 history, force, torque, own, max_overlap, dt, nblock):
    """Forces of every image candidate on its grain, added to own (after
    contacts.contact_forces, in the same ``nblock`` blocks of grains); returns the
    energies dissipated [J] (normal, tangential: half of each contact's, module
    docstring) and the image contacts that start.  owner : the grain of each candidate
    (Images.scratch_ids); law : bundles.LawWorkspace (its sums and collisions are
    reused)."""
    n = positions.shape[0]
    address, work, slots, sums, started = law.address, law.work, law.slots, law.sums, \
        law.collisions
    if nblock == 1:
        return _image_block(np.int64(0), n, address, work[0], slots[0], model, params,
                            positions, velocities, angular_velocities, radii, masses,
                            materials, fixed, periodic_flag, periodic_length, at, start,
                            codes, owner, history, force, torque, own, max_overlap, dt)
    for b in prange(nblock):
        sums[b, 0], sums[b, 1], started[b, 0] = _image_block(
            b * n // nblock, (b + 1) * n // nblock, address, work[b], slots[b], model, params,
            positions, velocities, angular_velocities, radii, masses, materials, fixed,
            periodic_flag, periodic_length, at, start, codes, owner, history, force, torque,
            own, max_overlap, dt)
    total_n, total_t, total, unused = block_total(sums, started, nblock)
    return total_n, total_t, total
