"""The compiled time loop: many steps per call, Python only between chunks.

One step (the order is fixed here and nowhere else):
  1. for each integrator stage: drift/predict; at the first stage, when some grain
     (or wall) may have moved more than half the skin, return RELIST (the caller
     rebuilds the neighbour lists with ``relist`` and calls again, which goes on from
     there), then move prescribed walls; contact forces (pairs, then walls), then one
     pass over grains that gathers their contact forces,
     corrects the velocities and bounds the displacement for the next step's check
     (integrators/passes.py; the integrator's own history is ``integrator_history``).
     The last pass of a step also does the next step's first drift, unless the step
     ends the chunk or is checked;
  2. time += dt, step += 1, and one more step of integrator history (HISTORY_STEPS,
     0 until the first step: multi-step schemes then use their start-up formulas);
  3. every ``check_interval`` steps: NaN, excessive overlap, and the stop condition.
The first step of a run first builds the lists and evaluates the forces at the start.
Dissipated energies and the work of moving walls are accumulated in ``clock``, the
collisions (contacts that start, contacts.touch) in ``counters``: COLLISIONS (grain
pairs) and WALL_COLLISIONS, at every evaluation of a step but not at the priming
one, whose contacts were there when the run (or a relocation) put the grains.

The kernels take their arrays in the named bundles of engines/soft/bundles.py (grains:
Grains, pairs: Pairs, walls: WallBundle, images: Images, law: LawWorkspace) and of
core.walls (periodic: PeriodicBox), and
read them by field name (``grains.radii``, ``walls.offset``).

run_chunk and what it calls every step are compiled without reference counting
(_jit.driver): with it, each call into a pass counted every array of the bundles in
and out, about 2.3 us per step whatever the number of grains (BENCHMARKS.md).  They
allocate nothing; the rebuild, which does, runs from Python between two calls.
"""
import math

import numpy as np

from ..._jit import driver, kernel, scalar
from ...core.neighbors import rebuild
from ...core.triggers import ENERGY_RATIO_BELOW, MAX_SPEED_BELOW
from ...core.walls import walls_advance
from .contacts import PAIRS, PLANAR, WALLS, contact_forces, largest
from .image_contacts import image_forces
from .integrators import STAGES, after_force, before_force

# return codes of run_chunk (and relist: DONE, GROW, NAN)
DONE, CONDITION, GROW, NAN, OVERLAP, RELIST = 0, 1, 2, 3, 4, 5
# clock (float64) slots
TIME, DT, SKIN, GX, GY, GZ, COND_VALUE, OVERLAP_LIMIT, DISS_N, DISS_T, WALL_WORK, MOVE = \
    range(12)
# counters (int64) slots
STEP, DIM, INTEGRATOR, REBUILDS, FORCE_REBUILD, CHECK_INTERVAL, COND_KIND, PRIMED, \
    NEED_PAIRS, NEED_WALLS, HISTORY_STEPS, COLLISIONS, WALL_COLLISIONS = range(13)
NCOUNTERS = 13
# counters[FORCE_REBUILD]: 1 forced; RELISTED: the lists were just rebuilt for the step
# run_chunk returned RELIST in (after its first drift, or before the priming evaluation)
RELISTED = 3


def new_clock(dt, skin, gravity):
    """The float64 clock array of a simulation."""
    clock = np.zeros(12)
    clock[DT] = dt
    clock[SKIN] = skin
    clock[GX:GZ + 1] = gravity
    clock[OVERLAP_LIMIT] = np.inf
    return clock


@driver
def evaluate_forces(model, params, law, grains, pairs, walls, periodic, images, gravity, dt,
                    nblock, dim):
    """All contact forces (pairs, walls, then the images of the symmetry planes,
    image_contacts.image_forces) and the total force on each wall in a ``dim``-D system;
    returns the (normal, tangential) energy dissipated [J], the power of the walls on
    the grains [W], and the grain-pair and grain-wall contacts that started
    (collisions, contacts.touch).
    law: the batched law of the contacts (contacts.contact_forces);
    nblock: blocks of grains handed to threads (contacts.block_count).  The owners of
    the pairs and wall candidates are the lists' scratch_partners and scratch_wall_ids
    (neighbors.list_owners)."""
    parts = PAIRS | WALLS
    if dim == 2:
        parts |= PLANAR
    dn, dt_, pair_collisions, wall_collisions = contact_forces(
        model, params, law, grains.positions, grains.velocities, grains.angular_velocities,
        grains.radii, grains.masses, grains.materials, grains.fixed, periodic.flag,
        periodic.length, pairs.start, pairs.partners, pairs.scratch_partners, pairs.history,
        pairs.force, pairs.torque_j, walls.kind, walls.geometry, walls.offset, walls.velocity,
        walls.material, walls.wall_start, walls.wall_ids, walls.scratch_wall_ids,
        walls.wall_history, walls.contact_force, walls.contact_torque, pairs.own,
        grains.max_overlap, dt, nblock, np.int64(parts))
    if images.start[grains.masses.size] > 0:
        image_n, image_t, image_collisions = image_forces(
            model, params, law, grains.positions, grains.velocities,
            grains.angular_velocities, grains.radii, grains.masses, grains.materials,
            grains.fixed, periodic.flag, periodic.length, images.at, images.start, images.ids,
            images.scratch_ids, images.history, images.force, images.torque, pairs.own,
            grains.max_overlap, dt, nblock)
        dn += image_n
        dt_ += image_t
        pair_collisions += image_collisions
    force, contact_force, velocity, wall_ids = \
        walls.force, walls.contact_force, walls.velocity, walls.wall_ids
    force[:] = 0.0
    power = 0.0
    for q in range(walls.wall_start[grains.masses.size]):   # every candidate, in grain order
        w = wall_ids[q]
        for d in range(3):
            force[w, d] -= contact_force[q, d]
            power += contact_force[q, d] * velocity[w, d]
    return dn, dt_, power, pair_collisions, wall_collisions


@kernel
def _energies(velocities, angular_velocities, positions, masses, inertias, fixed, gravity):
    """Kinetic energy [J] of free grains and their potential energy [J] above the lowest."""
    g = math.sqrt(gravity[0] ** 2 + gravity[1] ** 2 + gravity[2] ** 2)
    kinetic = 0.0
    low = np.inf
    for i in range(masses.size):
        if fixed[i]:
            continue
        v2 = 0.0
        w2 = 0.0
        for d in range(3):
            v2 += velocities[i, d] ** 2
            w2 += angular_velocities[i, d] ** 2
        kinetic += 0.5 * masses[i] * v2 + 0.5 * inertias[i] * w2
        if g > 0.0:
            low = min(low, -(positions[i, 0] * gravity[0] + positions[i, 1] * gravity[1]
                             + positions[i, 2] * gravity[2]) / g)
    potential = 0.0
    if g > 0.0:
        for i in range(masses.size):
            if not fixed[i]:
                h = -(positions[i, 0] * gravity[0] + positions[i, 1] * gravity[1]
                      + positions[i, 2] * gravity[2]) / g
                potential += masses[i] * g * (h - low)
    return kinetic, potential


@driver
def _all_finite(positions):
    """True when every coordinate is finite (checked before a neighbour rebuild, which
    cannot grid NaN or infinite positions)."""
    for i in range(positions.shape[0]):
        for d in range(positions.shape[1]):
            if not math.isfinite(positions[i, d]):
                return False
    return True


@scalar
def verdict(finite, worst, speed2, kinetic, potential, kind, clock):
    """The status of a checked step from its measures: NAN unless every position,
    velocity and force is finite, OVERLAP when the largest overlap ``worst`` [m] passes
    the limit, CONDITION when the stop condition ``kind`` holds (largest speed
    sqrt(speed2) [m/s], or kinetic over potential energy [J]), else DONE.  Shared with
    the GPU's per-system check."""
    if not finite:
        return NAN
    if worst > clock[OVERLAP_LIMIT]:
        return OVERLAP
    if kind == MAX_SPEED_BELOW and math.sqrt(speed2) < clock[COND_VALUE]:
        return CONDITION
    if kind == ENERGY_RATIO_BELOW and kinetic <= clock[COND_VALUE] * potential:
        return CONDITION
    return DONE


@driver
def _checks(grains, counters, clock):
    """NaN, overlap and stop-condition checks (``verdict``); returns a status code."""
    positions, velocities, forces, masses, fixed, max_overlap = \
        grains.positions, grains.velocities, grains.forces, grains.masses, grains.fixed, \
        grains.max_overlap
    vmax = 0.0
    for i in range(masses.size):
        v2 = 0.0
        for d in range(3):
            if not (math.isfinite(positions[i, d]) and math.isfinite(velocities[i, d])
                    and math.isfinite(forces[i, d])):
                return NAN
            v2 += velocities[i, d] ** 2
        if not fixed[i]:
            vmax = max(vmax, v2)
    worst = largest(max_overlap)
    max_overlap[:] = 0.0
    kind = counters[COND_KIND]
    kinetic = potential = 0.0
    if kind == ENERGY_RATIO_BELOW and worst <= clock[OVERLAP_LIMIT]:
        kinetic, potential = _energies(velocities, grains.angular_velocities, positions,
                                       masses, grains.inertias, fixed, clock[GX:GZ + 1])
    return verdict(True, worst, vmax, kinetic, potential, kind, clock)


@driver
def rebuild_due(clock, offset, reference_offset, velocity):
    """The half-skin rule: True when some grain (clock[MOVE], the bound of the last
    correction) plus the walls (displacement since the last build + 2 |v| dt) may have
    moved more than the skin by the end of this step.  Shared with the GPU."""
    dt = clock[DT]
    wall_move = 0.0
    for w in range(offset.shape[0]):
        d2 = 0.0
        v2 = 0.0
        for d in range(3):
            d2 += (offset[w, d] - reference_offset[w, d]) ** 2
            v2 += velocity[w, d] ** 2
        wall_move = max(wall_move, math.sqrt(d2) + 2.0 * math.sqrt(v2) * dt)
    grain_move = clock[MOVE]
    return grain_move + max(grain_move, wall_move) > clock[SKIN]


@driver
def _after(integrator, stage, dt, counters, gravity, grains, pairs, periodic,
           integrator_history, block_scratch, drift_next):
    """integrators.after_force with the arrays it needs taken out of the bundles."""
    return after_force(integrator, stage, dt, counters[HISTORY_STEPS] > 0, counters[DIM],
                       gravity, pairs, grains.forces, grains.torques, grains.masses,
                       grains.inertias, grains.positions, grains.reference_positions,
                       grains.velocities, grains.angular_velocities, grains.orientations,
                       grains.accelerations, grains.angular_accelerations, grains.fixed,
                       periodic.flag, periodic.length, integrator_history, block_scratch,
                       drift_next)


@kernel
def relist(grains, pairs, walls, periodic, clock, counters, law):
    """Rebuild the neighbour lists (run_chunk returned RELIST); returns DONE (and
    counters[FORCE_REBUILD] = RELISTED), NAN (non-finite positions) or GROW (capacity
    short: counters say how much is needed, nothing has changed)."""
    if not _all_finite(grains.positions):
        return NAN
    needed, wall_needed = rebuild(
        grains.positions, grains.radii, clock[SKIN], periodic.flag, periodic.lo,
        periodic.length, pairs.start, pairs.partners, pairs.history, pairs.scratch_start,
        pairs.scratch_partners, pairs.scratch_history, pairs.reverse_start,
        pairs.reverse_pairs, walls.kind, walls.geometry, walls.offset, walls.wall_start,
        walls.wall_ids, walls.wall_history, walls.scratch_wall_start, walls.scratch_wall_ids,
        walls.scratch_wall_history, grains.reference_positions, walls.reference_offset)
    if needed > pairs.partners.size or wall_needed > walls.wall_ids.size:
        counters[NEED_PAIRS] = needed
        counters[NEED_WALLS] = wall_needed
        return GROW
    counters[FORCE_REBUILD] = RELISTED
    counters[REBUILDS] += 1
    law.dirty[:] = 1       # new pair slots: every one may hold force or history
    return DONE


@scalar
def _lists_ready(clock, counters, walls):
    """True when the step may use the lists as they are: just rebuilt (RELISTED, then
    cleared), or neither forced nor due (rebuild_due); else run_chunk returns RELIST."""
    if counters[FORCE_REBUILD] == RELISTED:
        counters[FORCE_REBUILD] = 0
        return True
    return counters[FORCE_REBUILD] == 0 and not rebuild_due(clock, walls.offset,
                                                            walls.reference_offset,
                                                            walls.velocity)


@driver
def run_chunk(model, params, law, grains, pairs, walls, periodic, images, clock, counters,
              integrator_history, block_scratch, nsteps):
    """Advance up to ``nsteps`` steps; returns (status, steps done).  On RELIST the
    step ``done`` is under way: call relist, then run_chunk for the steps left.
    integrator_history : (slots, N, 3) the integrator's own per-grain history
    (integrators/ids.py)."""
    dt = clock[DT]
    gravity = clock[GX:GZ + 1]
    integrator = counters[INTEGRATOR]
    # lists rebuilt after the step's drift (a RELIST return): the grains are drifted
    drifted = counters[FORCE_REBUILD] == RELISTED and counters[PRIMED] != 0
    for s in range(nsteps):
        if counters[PRIMED] == 0:
            if not _lists_ready(clock, counters, walls):
                return RELIST, s
            evaluate_forces(model, params, law, grains, pairs, walls, periodic, images, gravity,
                            0.0, block_scratch.size, counters[DIM])
            # stage and drift_next as a plain int64 and bool: literals would compile the
            # pass a second time
            clock[MOVE] = _after(integrator, np.int64(0), 0.0, counters, gravity, grains,
                                 pairs, periodic, integrator_history, block_scratch, s < 0)
            counters[PRIMED] = 1
            # grains that start too deep in each other or in a wall: stop before moving
            if largest(grains.max_overlap) > clock[OVERLAP_LIMIT]:
                return OVERLAP, s
        last = STAGES[integrator] - 1
        for stage in range(last + 1):
            if not drifted:
                before_force(integrator, stage, dt, counters[HISTORY_STEPS] > 0,
                             counters[DIM], grains.positions, grains.velocities, grains.angular_velocities,
                             grains.orientations, grains.accelerations,
                             grains.angular_accelerations, grains.fixed, integrator_history)
            drifted = False
            if stage == 0:
                if not _lists_ready(clock, counters, walls):
                    return RELIST, s
                walls_advance(walls.motion_kind, walls.motion, walls.base, walls.offset,
                              walls.velocity, walls.force, clock[TIME], dt)
            # each force evaluation stands for its share of the step (the optimized
            # velocity Verlet kicks h/2 twice): contact-history increments, dissipation
            # and wall work advance by that share, not by the whole step
            share = dt / STAGES[integrator]
            dn, dtan, power, pair_collisions, wall_collisions = evaluate_forces(
                model, params, law, grains, pairs, walls, periodic, images, gravity, share,
                block_scratch.size, counters[DIM])
            counters[COLLISIONS] += pair_collisions
            counters[WALL_COLLISIONS] += wall_collisions
            clock[DISS_N] += dn
            clock[DISS_T] += dtan
            clock[WALL_WORK] += power * share
            # the next step's first drift rides on the last pass over the grains, unless
            # the step ends the chunk or is checked (the state is then seen as it is)
            drifted = stage == last and s + 1 < nsteps \
                and (counters[STEP] + 1) % counters[CHECK_INTERVAL] != 0
            clock[MOVE] = _after(integrator, stage, dt, counters, gravity, grains, pairs,
                                 periodic, integrator_history, block_scratch, drifted)
        clock[TIME] += dt
        counters[STEP] += 1
        counters[HISTORY_STEPS] += 1
        if counters[STEP] % counters[CHECK_INTERVAL] == 0 or s == nsteps - 1:
            status = _checks(grains, counters, clock)
            if status != DONE:
                return status, s + 1
    return DONE, nsteps
