"""One Moreau-Jean step of rigid grains, and the compiled loop of many (Pérez Sec. 2,
Eq. 11-12; Jean 1999, theta method).  Over the step [t, t + dt]:

  v+ = v- + dt g + M^-1 H^T P                    (Eq. 12: impulses P = dt F(t + dt))
  r+ = r- + dt ((1 - theta) v- + theta v+)       (Eq. 11 at theta = 1)
  w+ = w- + I^-1 (a x P),  orientation turned by dt ((1 - theta) w- + theta w+)

P from the NLGS (solver.py) with, at each listed contact of gap g < ``gap`` at the start
of the step (detection.py), the normal bound b of its velocity u+ at the end of the step
(u- at the start, u_n > 0 separating):

  b = -max(g, 0) / (theta dt)      (an open contact may close, not overshoot, in the step)
  b = max(-e u-, that)  when the contact is impacting: u- < 0 and g + dt u- <= 0
                        (Newton's restitution e of the pair of materials).

So a contact closing within the step is caught at its start, a resting contact keeps its
gap, and an impact gives u+ = -e u- (at theta = 1 exactly where the impact starts within
|u-| dt of contact).  At theta = 1 the gap at the end of the step is g + dt u+ >= 0: no
interpenetration.  At theta < 1 the end gap is g + dt (theta u+ + (1 - theta) u-), and an
impact that starts closer than (1 - theta)(1 - e)|u-| dt leaves a penetration of at most
that; a penetrated contact (g < 0) is held at u+ >= 0, never pushed out (which would
return energy), until it opens.  (Keeping the term (1 - theta) u- in b instead, so that
the end gap is never negative, makes every touching impact at theta = 1/2 perfectly
elastic: a grain on a floor then chatters for ever.)

Walls move by their prescribed motion (core.walls.walls_advance) before the solve; the
velocity of a servo wall or a piston (a wall of a mass) is solved with the impulses
(solver.solved_velocity) and its offset corrected to it after the solve: the piston's
momentum balance M (s+ - s-) = dt F_applied - sum P . u is then implicit, with this
step's impulses, as the grains' own.

Energy: the step's loss D = -(dK + dV) + W_walls (K kinetic with rotation, V = -m g.r,
W_walls = sum P . v_wall over wall contacts) is exact for the discrete step;
friction's share -sum P_t . (u_t,free + u_t+)/2 (the work of the tangential impulses on
the contact points between the free and final velocities), with rolling resistance's
-sum C . (w_r,free + w_r+)/2 (the couples on the relative spins), is
dissipated_tangential,
the rest dissipated_normal (impacts, and the numerical dissipation of theta > 1/2:
dt^2 |g|^2 / 2 per grain and step at theta = 1 in free flight, zero at theta = 1/2).
A loss within the rounding of the energies it is the difference of (ROUNDING of them)
counts as none, so that an elastic, frictionless run dissipates exactly nothing.
"""
import math

import numpy as np

from ..._jit import kernel, scalar
from ...core.walls import PISTON, SERVO, walls_advance
from ..rigid import DONE, stop_status
from .detection import IMPULSE_WIDTH, contact_geometry, moved_beyond, relist
from .solver import (apply_couple, apply_impulse, arm, contact_velocity, nlgs,
                     relative_spin)

# return codes of advance
GROW = 2                 # the arrays must grow (rigid.py: DONE, CONDITION, NAN)
# clock (float64) slots
TIME, DT, THETA, GAP, MARGIN, GX, GY, GZ, TOLERANCE, COND_VALUE, DISS_N, DISS_T, \
    WALL_WORK, RESIDUAL, WORST_RESIDUAL = range(15)
NCLOCK = 15
# counters (int64) slots
STEP, MAX_ITERATIONS, ITERATIONS, NOT_CONVERGED, COND_KIND, REBUILDS, FORCE_REBUILD, \
    NEED_PAIRS, NEED_WALLS, TOTAL_ITERATIONS, FIRST_STEP = range(11)
NCOUNTERS = 11
# a step's energy loss within this many machine epsilons of the energies it is the
# difference of is rounding, counted as none
ROUNDING = 64 * 2.220446049250313e-16


@kernel
def _bounds(velocities, angular_velocities, radii, materials, lists, wall_material,
            wall_velocity, restitution, clock, active, wall_active, bound, wall_bound):
    """Mark the contacts of the step (gap < clock[GAP]) and their normal bounds b [m/s]
    from the velocities at the start of the step (module docstring); returns the
    largest |b| and |u_n-| [m/s], the solver's velocity scale."""
    n = radii.size
    dt, theta, gap = clock[DT], clock[THETA], clock[GAP]
    largest = 0.0
    for k in range(lists.start[n] + lists.wall_start[n]):
        wall = k >= lists.start[n]
        q = k - lists.start[n]
        if wall:
            g = lists.wall_gap[q]
            i = lists.wall_owner[q]
            w = lists.wall_ids[q]
            j = -1
            nx, ny, nz = lists.wall_normal[q, 0], lists.wall_normal[q, 1], \
                lists.wall_normal[q, 2]
            vx, vy, vz = wall_velocity[w, 0], wall_velocity[w, 1], wall_velocity[w, 2]
            e = restitution[materials[i], wall_material[w]]
            rj = 0.0
        else:
            g = lists.gap[k]
            i = lists.owner[k]
            j = np.int64(lists.partners[k])
            nx, ny, nz = lists.normal[k, 0], lists.normal[k, 1], lists.normal[k, 2]
            vx, vy, vz = 0.0, 0.0, 0.0
            e = restitution[materials[i], materials[j]]
            rj = radii[j]
        on = g < gap
        b = 0.0
        if on:
            ux, uy, uz = contact_velocity(velocities, angular_velocities, i, j, radii[i], rj,
                                          nx, ny, nz, vx, vy, vz)
            un = ux * nx + uy * ny + uz * nz
            b = -max(g, 0.0) / (theta * dt)
            if un < 0.0 and g + dt * un <= 0.0:
                b = max(b, -e * un)
            largest = max(largest, abs(b), abs(un))
        if wall:
            wall_active[q] = on
            wall_bound[q] = b
            if not on:
                for d in range(IMPULSE_WIDTH):
                    lists.wall_impulses[q, d] = 0.0
        else:
            active[k] = on
            bound[k] = b
            if not on:
                for d in range(IMPULSE_WIDTH):
                    lists.impulses[k, d] = 0.0
    return largest


@scalar
def contact_slot(k, n, lists, radii, wall_velocity, active, wall_active):
    """Entry k of the walk over every listed pair, then every wall candidate, of ``n``
    grains: (on, wall, slot, i, j, w, r_j, v_wall (3)).  on: the contact is active;
    slot: its row in the pair (or wall) arrays; j = -1 and r_j = 0 for a wall contact,
    w = -1 and v_wall = 0 for a pair."""
    if k >= lists.start[n]:
        q = k - lists.start[n]
        w = np.int64(lists.wall_ids[q])
        return (wall_active[q] != 0, True, q, np.int64(lists.wall_owner[q]), np.int64(-1), w,
                0.0, wall_velocity[w, 0], wall_velocity[w, 1], wall_velocity[w, 2])
    j = np.int64(lists.partners[k])
    return (active[k] != 0, False, k, np.int64(lists.owner[k]), j, np.int64(-1), radii[j],
            0.0, 0.0, 0.0)


@kernel
def _free_and_warm(velocities, angular_velocities, inv_mass, inv_inertia, radii, materials,
                   lists, wall_material, wall_velocity, active, wall_active, friction,
                   rolling, free, wall_free):
    """Keep the free relative velocities and spins (after gravity, before any impulse)
    of the active contacts in ``free``/``wall_free`` (for the energy split), then apply
    last step's impulses as the solver's start (warm start): projected on the present
    normal (compressive part only) and cut to the friction cone mu_s P_n, the couple
    to the tangent plane and to mu_r R* P_n."""
    n = radii.size
    for k in range(lists.start[n] + lists.wall_start[n]):
        on, wall, slot, i, j, w, rj, vx, vy, vz = contact_slot(
            k, n, lists, radii, wall_velocity, active, wall_active)
        if not on:
            continue
        if wall:
            normal, store = lists.wall_normal, wall_free
        else:
            normal, store = lists.normal, free
        nx, ny, nz = normal[slot, 0], normal[slot, 1], normal[slot, 2]
        store[slot, 0], store[slot, 1], store[slot, 2] = contact_velocity(
            velocities, angular_velocities, i, j, radii[i], rj, nx, ny, nz, vx, vy, vz)
        store[slot, 3], store[slot, 4], store[slot, 5] = relative_spin(angular_velocities,
                                                                       i, j)
    for k in range(lists.start[n] + lists.wall_start[n]):
        on, wall, slot, i, j, w, rj, vx, vy, vz = contact_slot(
            k, n, lists, radii, wall_velocity, active, wall_active)
        if not on:
            continue
        if wall:
            mu_s = friction[materials[i], wall_material[w], 0]
            mu_r = rolling[materials[i], wall_material[w]]
            normal, impulses = lists.wall_normal, lists.wall_impulses
        else:
            mu_s = friction[materials[i], materials[j], 0]
            mu_r = rolling[materials[i], materials[j]]
            normal, impulses = lists.normal, lists.impulses
        nx, ny, nz = normal[slot, 0], normal[slot, 1], normal[slot, 2]
        px, py, pz = impulses[slot, 0], impulses[slot, 1], impulses[slot, 2]
        pn = px * nx + py * ny + pz * nz
        tx, ty, tz = px - pn * nx, py - pn * ny, pz - pn * nz
        pn = max(pn, 0.0)
        pt = math.sqrt(tx * tx + ty * ty + tz * tz)
        cut = 1.0 if pt <= mu_s * pn else mu_s * pn / pt
        px, py, pz = pn * nx + cut * tx, pn * ny + cut * ty, pn * nz + cut * tz
        impulses[slot, 0], impulses[slot, 1], impulses[slot, 2] = px, py, pz
        apply_impulse(velocities, angular_velocities, inv_mass, inv_inertia, i, j,
                      radii[i], rj, nx, ny, nz, px, py, pz)
        cx, cy, cz = impulses[slot, 3], impulses[slot, 4], impulses[slot, 5]
        cn = cx * nx + cy * ny + cz * nz
        cx, cy, cz = cx - cn * nx, cy - cn * ny, cz - cn * nz
        size = math.sqrt(cx * cx + cy * cy + cz * cz)
        limit = mu_r * arm(radii[i], rj) * pn
        cut = 1.0 if size <= limit else limit / size
        cx, cy, cz = cut * cx, cut * cy, cut * cz
        impulses[slot, 3], impulses[slot, 4], impulses[slot, 5] = cx, cy, cz
        apply_couple(angular_velocities, inv_inertia, i, j, cx, cy, cz)


@kernel
def _energy(velocities, angular_velocities, masses, inertias, fixed):
    """Kinetic energy (translational + rotational) of the free grains [J]."""
    total = 0.0
    for i in range(masses.size):
        if fixed[i]:
            continue
        for d in range(3):
            total += 0.5 * (masses[i] * velocities[i, d] ** 2
                            + inertias[i] * angular_velocities[i, d] ** 2)
    return total


@kernel
def _contact_work(velocities, angular_velocities, radii, lists, wall_velocity, active,
                  wall_active, free, wall_free, wall_force, dt):
    """After the solve: the friction and rolling loss -sum P_t . (u_t,free + u_t+)/2
    - sum C . (w_r,free + w_r+)/2 [J], the work of the walls sum P . v_wall [J]; writes
    the force of the grains on each wall, -sum P / dt [N], into ``wall_force``."""
    n = radii.size
    friction_loss = 0.0
    work = 0.0
    wall_force[:, :] = 0.0
    for k in range(lists.start[n] + lists.wall_start[n]):
        on, wall, slot, i, j, w, rj, vx, vy, vz = contact_slot(
            k, n, lists, radii, wall_velocity, active, wall_active)
        if not on:
            continue
        if wall:
            normal, impulses, start_speed = lists.wall_normal, lists.wall_impulses, wall_free
        else:
            normal, impulses, start_speed = lists.normal, lists.impulses, free
        nx, ny, nz = normal[slot, 0], normal[slot, 1], normal[slot, 2]
        ux, uy, uz = contact_velocity(velocities, angular_velocities, i, j, radii[i], rj,
                                      nx, ny, nz, vx, vy, vz)
        ax = 0.5 * (ux + start_speed[slot, 0])
        ay = 0.5 * (uy + start_speed[slot, 1])
        az = 0.5 * (uz + start_speed[slot, 2])
        an = ax * nx + ay * ny + az * nz
        px, py, pz = impulses[slot, 0], impulses[slot, 1], impulses[slot, 2]
        pn = px * nx + py * ny + pz * nz
        friction_loss -= (px - pn * nx) * (ax - an * nx) + (py - pn * ny) * (ay - an * ny) \
            + (pz - pn * nz) * (az - an * nz)
        sx, sy, sz = relative_spin(angular_velocities, i, j)
        friction_loss -= 0.5 * (impulses[slot, 3] * (sx + start_speed[slot, 3])
                                + impulses[slot, 4] * (sy + start_speed[slot, 4])
                                + impulses[slot, 5] * (sz + start_speed[slot, 5]))
        if wall:
            work += px * vx + py * vy + pz * vz
            wall_force[w, 0] -= px / dt
            wall_force[w, 1] -= py / dt
            wall_force[w, 2] -= pz / dt
    return friction_loss, work


@kernel
def _move(positions, velocities, angular_velocities, orientations, old_velocities,
          old_angular_velocities, masses, fixed, gravity, dt, theta):
    """r += dt ((1 - theta) v- + theta v+) (Eq. 11 at theta = 1), orientations turned by
    dt ((1 - theta) w- + theta w+); returns the gravitational energy change
    -sum m g . dr [J] of the free grains."""
    change = 0.0
    for i in range(masses.size):
        if fixed[i]:
            continue
        for d in range(3):
            step = dt * ((1.0 - theta) * old_velocities[i, d] + theta * velocities[i, d])
            positions[i, d] += step
            change -= masses[i] * gravity[d] * step
        wx = dt * ((1.0 - theta) * old_angular_velocities[i, 0]
                   + theta * angular_velocities[i, 0])
        wy = dt * ((1.0 - theta) * old_angular_velocities[i, 1]
                   + theta * angular_velocities[i, 1])
        wz = dt * ((1.0 - theta) * old_angular_velocities[i, 2]
                   + theta * angular_velocities[i, 2])
        angle = math.sqrt(wx * wx + wy * wy + wz * wz)
        if angle > 0.0:        # q <- (cos(a/2), sin(a/2) w/|w|) q, renormalised
            c = math.cos(0.5 * angle)
            f = math.sin(0.5 * angle) / angle
            rx, ry, rz = f * wx, f * wy, f * wz
            q0, q1, q2, q3 = orientations[i, 0], orientations[i, 1], orientations[i, 2], \
                orientations[i, 3]
            a0 = c * q0 - rx * q1 - ry * q2 - rz * q3
            a1 = c * q1 + rx * q0 + ry * q3 - rz * q2
            a2 = c * q2 - rx * q3 + ry * q0 + rz * q1
            a3 = c * q3 + rx * q2 - ry * q1 + rz * q0
            size = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3)
            orientations[i, 0] = a0 / size
            orientations[i, 1] = a1 / size
            orientations[i, 2] = a2 / size
            orientations[i, 3] = a3 / size
    return change


@kernel
def _solved_rows(walls, t, dt):
    """The rows of the walls solved with the impulses in the step ending at ``t`` [s]
    (solver.solved_velocity), with the velocity walls_advance moved them at: the servo
    walls and pistons whose motion has started.  A piston's free speed undoes the
    grains' force of the last step that walls_advance applied: s_free = v . u + dt F / M,
    F = -force . u."""
    for w in range(walls.motion_kind.size):
        kind = walls.motion_kind[w]
        started = t > walls.motion[w, 7]
        walls.solved[w, 0] = 0.0
        if started and kind == SERVO:
            walls.solved[w, 0] = 1.0
            for c in range(3):
                walls.solved[w, 4 + c] = walls.motion[w, 3 + c]
        elif started and kind == PISTON:
            walls.solved[w, 0] = 2.0
            speed = 0.0
            push = 0.0
            for d in range(3):
                speed += walls.velocity[w, d] * walls.motion[w, d]
                push -= walls.force[w, d] * walls.motion[w, d]
            walls.solved[w, 4] = speed + dt * push / walls.motion[w, 8]
            walls.solved[w, 5] = 1.0 / walls.motion[w, 8]
            walls.solved[w, 6] = 0.0
        for d in range(3):
            walls.solved[w, 1 + d] = walls.motion[w, d]
            walls.solved[w, 7 + d] = walls.velocity[w, d]


@kernel
def advance(grains, lists, walls, periodic, tables, work, clock, counters, nsteps):
    """Run up to ``nsteps`` Moreau-Jean steps (module docstring).  Returns (status, steps
    done): DONE, CONDITION (the stop condition holds after the last step), GROW (the
    lists need more room: counters NEED_PAIRS/NEED_WALLS; the step was not begun) or
    NAN.  Every step keeps the solver's sweeps and residual in counters[ITERATIONS] and
    clock[RESIDUAL], counts a step whose residual stays above the tolerance after
    max_iterations sweeps in counters[NOT_CONVERGED] (its largest residual in
    clock[WORST_RESIDUAL]); such a step is kept (its velocities satisfy the laws but to
    the residual) and reported by the engine."""
    dt, theta = clock[DT], clock[THETA]
    gravity = clock[GX:GZ + 1]
    positions, velocities, spins = grains.positions, grains.velocities, \
        grains.angular_velocities
    for s in range(nsteps):
        if counters[FORCE_REBUILD] or moved_beyond(
                positions, grains.reference_positions, walls.offset, walls.reference_offset,
                walls.velocity, dt, clock[MARGIN]):
            needed, wall_needed = relist(
                positions, grains.radii, clock[GAP] + clock[MARGIN], periodic.flag,
                periodic.lo, periodic.length, lists, walls.kind, walls.geometry,
                walls.offset, grains.reference_positions, walls.reference_offset)
            if needed > lists.partners.size or wall_needed > lists.wall_ids.size:
                counters[NEED_PAIRS] = needed
                counters[NEED_WALLS] = wall_needed
                return GROW, s
            counters[FORCE_REBUILD] = 0
            counters[REBUILDS] += 1
        contact_geometry(positions, grains.radii, periodic.flag, periodic.length, lists,
                         walls.kind, walls.geometry, walls.offset)
        walls_advance(walls.motion_kind, walls.motion, walls.base, walls.offset,
                      walls.velocity, walls.force, clock[TIME], dt)
        _solved_rows(walls, clock[TIME] + dt, dt)
        scale = _bounds(velocities, spins, grains.radii, grains.materials, lists,
                        walls.material, walls.velocity, tables.restitution, clock,
                        work.active, work.wall_active, work.bound, work.wall_bound)
        before = _energy(velocities, spins, grains.masses, grains.inertias, grains.fixed)
        grains.old_velocities[:, :] = velocities
        grains.old_angular_velocities[:, :] = spins
        for i in range(grains.radii.size):
            if not grains.fixed[i]:
                for d in range(3):
                    velocities[i, d] += dt * gravity[d]
        _free_and_warm(velocities, spins, grains.inv_mass, grains.inv_inertia, grains.radii,
                       grains.materials, lists, walls.material, walls.velocity, work.active,
                       work.wall_active, tables.friction, tables.rolling, work.free,
                       work.wall_free)
        g = math.sqrt(gravity[0] ** 2 + gravity[1] ** 2 + gravity[2] ** 2)
        sweeps, residual = nlgs(velocities, spins, grains.inv_mass, grains.inv_inertia,
                                grains.radii, grains.materials, lists, walls.material,
                                walls.velocity, work.active, work.wall_active, work.bound,
                                work.wall_bound, tables.friction, tables.rolling,
                                clock[TOLERANCE],
                                counters[MAX_ITERATIONS], max(scale, g * dt), walls.solved,
                                walls.push, dt)
        for w in range(walls.solved.shape[0]):      # solved walls: moved at the solved speed
            if walls.solved[w, 0] > 0.0:
                for d in range(3):
                    walls.offset[w, d] += (walls.velocity[w, d] - walls.solved[w, 7 + d]) * dt
        counters[ITERATIONS] = sweeps
        counters[TOTAL_ITERATIONS] += sweeps
        clock[RESIDUAL] = residual
        if residual > clock[TOLERANCE]:
            counters[NOT_CONVERGED] += 1
            clock[WORST_RESIDUAL] = max(clock[WORST_RESIDUAL], residual)
        friction_loss, wall_work = _contact_work(
            velocities, spins, grains.radii, lists, walls.velocity, work.active,
            work.wall_active, work.free, work.wall_free, walls.force, dt)
        potential = _move(positions, velocities, spins, grains.orientations,
                          grains.old_velocities, grains.old_angular_velocities,
                          grains.masses, grains.fixed, gravity, dt, theta)
        after = _energy(velocities, spins, grains.masses, grains.inertias, grains.fixed)
        loss = wall_work - (after - before) - potential
        if abs(loss) <= ROUNDING * (before + after + abs(potential) + abs(wall_work)):
            loss = 0.0
        clock[DISS_T] += friction_loss
        clock[DISS_N] += loss - friction_loss
        clock[WALL_WORK] += wall_work
        clock[TIME] += dt
        counters[STEP] += 1
        status = stop_status(velocities, spins, positions, grains.masses, grains.inertias,
                             grains.fixed, gravity, counters[COND_KIND], clock[COND_VALUE])
        if status != DONE:
            return status, s + 1
    return DONE, nsteps
