"""The event loop: predict each grain's next event, take the earliest from the calendar,
carry it out, predict again the grains it changed (Pérez Sec. 2's "typical
calculation"), all compiled, with no Python per event.

Events of a grain: its next collision (``Calendar.kind``: PAIR with grain ``partner``,
WALL with wall ``partner``, RECHECK a wall search to take up again (flight.wall_time),
NONE nothing ahead) and its next cell crossing (through ``Calendar.face`` = 2 axis +
(1 upper, 0 lower)); the calendar is keyed by the earlier of the two.  Grains are advanced lazily: each has its own clock
``Grains.local_time`` and is brought to the present only when an event involves it,
or at a synchronisation (``synchronise``) where the engine pauses; its orientation
only when its spin changes, or at a synchronisation (_turn).

Cells: a grid of cells at least a largest diameter wide, so a grain can touch only
grains of its own and the adjacent cells; leaving a cell is an event, after which the
grain's collision predicted before stands and only the grains of the newly adjacent
layer of cells are looked at (Rapaport).  Along a periodic
axis the grid spans the period and a grain that leaves the last cell enters the first
one, its coordinate shifted by the period; along the others the outermost cells reach
to infinity.

Stale events are recognised by collision counters (calendar.py).  A cascade of events
at one instant that does not end (inelastic collapse: the collisions of a cluster
pile up until their times no longer differ in floating point) stops the loop with
status COLLAPSE instead of running on forever.
"""
import math

import numpy as np

from ..._jit import block_body, driver
from ...core.rotation import rotate_quaternion
from . import flight
from .calendar import build, front, reschedule
from .collision import TC as TC_MODEL, collision_impulse, contact_velocity, restitution_now

NONE, PAIR, WALL, RECHECK = 0, 1, 2, 3
# clock (float64) slots
(TIME, GX, GY, GZ, DISS_N, DISS_T, WALL_WORK, VIRIAL, TANGENTIAL, COLLAPSE_SPEED,
 CONTACT_DURATION, TOLERANCE, NCLOCK) = range(13)
# counters (int64) slots
(EVENTS, PAIR_COLLISIONS, WALL_COLLISIONS, CROSSINGS, RECHECKS, STALE, COLLAPSE_MODEL,
 SAME_TIME, NCOUNTERS) = range(9)
# loop status
DONE, COLLAPSED = 0, 1
SAME_TIME_LIMIT = 100_000        # events at one instant that make a collapse


@block_body
def _advance(g, i, t, straight):
    """Bring grain i's centre from its own time to time t [s] by free flight (a parabola;
    its orientation is turned apart, by _turn, when its spin changes or at a
    synchronisation: spin is constant in flight, so the turn is exact whenever it is
    done, and most events, the cell crossings, never touch it).  ``straight`` (a
    constant in the caller's copy: no gravity and no held grain) drops the terms that
    are then zero."""
    dt = t - g.local_time[i]
    if straight:
        if dt != 0.0:
            for d in range(3):
                g.positions[i, d] += dt * g.velocities[i, d]
        g.local_time[i] = t
        return
    if dt != 0.0 and g.fixed[i] == 0:
        for d in range(3):
            g.positions[i, d] += dt * (g.velocities[i, d] + 0.5 * dt * g.gravity[d])
            g.velocities[i, d] += dt * g.gravity[d]
    g.local_time[i] = t


@block_body
def _turn(g, i, t, since):
    """Turn grain i's orientation by w (t - t0) (the exact rotation), t0 [s] the time it
    was left at: its last collision, or ``since`` [s], the time every grain was last
    brought to, if later.  Called before its spin changes (then its last collision is
    set to t) and at a synchronisation."""
    if g.fixed[i] != 0:
        return
    dt = t - max(g.last_collision[i], since)
    w = g.angular_velocities[i]
    if dt != 0.0 and (w[0] != 0.0 or w[1] != 0.0 or w[2] != 0.0):
        q = g.orientations[i]
        q[0], q[1], q[2], q[3] = rotate_quaternion(q[0], q[1], q[2], q[3], w[0] * dt,
                                                   w[1] * dt, w[2] * dt)


@block_body
def _wrap(box, k, d):
    """d [m] along axis k wrapped to its minimum image."""
    if box.flag[k]:
        return d - box.length[k] * math.floor(d / box.length[k] + 0.5)
    return d


@block_body
def _relative(g, i, j, t, straight):
    """r_i - r_j [m] (not wrapped) and v_i - v_j [m/s] at time t, grain i being at t:
    (dx, dy, dz, ux, uy, uz).  ``straight``: no gravity and no held grain (the same
    numbers, fewer terms)."""
    dt = t - g.local_time[j]
    p = g.positions
    v = g.velocities
    if straight:
        return (p[i, 0] - p[j, 0] - dt * v[j, 0], p[i, 1] - p[j, 1] - dt * v[j, 1],
                p[i, 2] - p[j, 2] - dt * v[j, 2], v[i, 0] - v[j, 0], v[i, 1] - v[j, 1],
                v[i, 2] - v[j, 2])
    m = 1.0 if g.fixed[j] == 0 else 0.0
    gx = g.gravity[0]
    gy = g.gravity[1]
    gz = g.gravity[2]
    vx = m * (v[j, 0] + dt * gx)
    vy = m * (v[j, 1] + dt * gy)
    vz = m * (v[j, 2] + dt * gz)
    dx = p[i, 0] - p[j, 0] - m * dt * (v[j, 0] + 0.5 * dt * gx)
    dy = p[i, 1] - p[j, 1] - m * dt * (v[j, 1] + 0.5 * dt * gy)
    dz = p[i, 2] - p[j, 2] - m * dt * (v[j, 2] + 0.5 * dt * gz)
    return dx, dy, dz, v[i, 0] - vx, v[i, 1] - vy, v[i, 2] - vz


@block_body
def _separation(g, box, i, j, t, straight):
    """r_i - r_j [m] (minimum image) and v_i - v_j [m/s] at time t, grain i being at t:
    (dx, dy, dz, ux, uy, uz)."""
    dx, dy, dz, ux, uy, uz = _relative(g, i, j, t, straight)
    return _wrap(box, 0, dx), _wrap(box, 1, dy), _wrap(box, 2, dz), ux, uy, uz


@block_body
def _cell_range(cells, box, c, axis):
    """The cells next to cell c along ``axis`` (c included), without repeats: (first,
    count), the cells being first + k for k < count, unwrapped (_image wraps them)."""
    n = cells.count[axis]
    if box.flag[axis]:
        if n >= 3:
            return c - 1, 3
        return 0, n
    first = max(c - 1, 0)
    return first, min(c + 1, n - 1) - first + 1


@block_body
def _image(cells, box, raw, axis):
    """The cell of unwrapped index ``raw`` along ``axis`` and the shift [m] that takes
    r_i - r_j to the image of a grain j there next to grain i: (cell, shift)."""
    n = cells.count[axis]
    if raw < 0:
        return raw + n, box.length[axis]
    if raw >= n:
        return raw - n, -box.length[axis]
    return raw, 0.0


@block_body
def _wrapped(cells, box, axis):
    """True along a periodic axis of fewer than 4 cells, where a grain of a neighbour
    cell may be nearer through another image (with 4 or more, a neighbour is at most 2
    cells, half the period, away): the separation is then wrapped to its minimum
    image."""
    return box.flag[axis] != 0 and cells.count[axis] < 4


@block_body
def _cell_bounds(cells, box, c, axis):
    """Lower and upper bound [m] of cell c along ``axis`` (infinite at the outer faces
    of a non-periodic axis)."""
    lo = cells.lo[axis] + c * cells.size[axis]
    hi = lo + cells.size[axis]
    if not box.flag[axis]:
        if c == 0:
            lo = -math.inf
        if c == cells.count[axis] - 1:
            hi = math.inf
    return lo, hi


@block_body
def _unlink(cells, i):
    c = cells.cell[i]
    if cells.prev[i] >= 0:
        cells.next[cells.prev[i]] = cells.next[i]
    else:
        cells.head[c] = cells.next[i]
    if cells.next[i] >= 0:
        cells.prev[cells.next[i]] = cells.prev[i]


@block_body
def _link(cells, i, c):
    cells.cell[i] = c
    cells.prev[i] = -1
    cells.next[i] = cells.head[c]
    if cells.head[c] >= 0:
        cells.prev[cells.head[c]] = i
    cells.head[c] = i


@block_body
def _schedule(cal, i, next_time, kind, partner, count, cross_time, face):
    """Put grain i's next collision (absolute time, kind, partner, partner's counter) and
    next cell crossing (absolute time, face) in the calendar, keyed by the earlier."""
    cal.next_time[i] = next_time
    cal.kind[i] = kind
    cal.partner[i] = partner
    cal.count[i] = count
    cal.cross_time[i] = cross_time
    cal.face[i] = face
    cal.time[i] = min(next_time, cross_time)
    reschedule(cal, i, cal.time[i])


@block_body
def _crossing(g, cells, box, i, straight):
    """The time [s] from now until grain i leaves its cell, and through which face."""
    best = math.inf
    face = -1
    for axis in range(3):
        lo, hi = _cell_bounds(cells, box, cells.coords[i, axis], axis)
        t, up = flight.boundary_time(g.positions[i, axis], g.velocities[i, axis],
                                     0.0 if straight else g.gravity[axis], lo, hi)
        if t < best:
            best = t
            face = 2 * axis + up
    return best, face


@block_body
def _scan_cell(g, cells, box, i, j, now, sx, sy, sz, wx, wy, wz, best, partner, count,
               straight):
    """_scan_pairs over the list of one cell, whose first grain is j, seen through the
    image that shifts the separation by (sx, sy, sz) [m] (wrapped to its minimum image
    along the axes where wx, wy, wz)."""
    reach_i = g.radii[i]
    while j >= 0:
        if j != i:
            dx, dy, dz, ux, uy, uz = _relative(g, i, j, now, straight)
            dx += sx
            dy += sy
            dz += sz
            if wx:
                dx = _wrap(box, 0, dx)
            if wy:
                dy = _wrap(box, 1, dy)
            if wz:
                dz = _wrap(box, 2, dz)
            t = flight.pair_time(dx, dy, dz, ux, uy, uz, reach_i + g.radii[j])
            if t < best:
                best = t
                partner = j
                count = g.collisions[j]
        j = cells.next[j]
    return best, partner, count


@block_body
def _scan_pairs(g, cells, box, i, now, fx, nx, fy, ny, fz, nz, best, partner, count,
                straight):
    """The earliest collision [s from now] of grain i with the grains of the block of
    cells fx + a, a < nx (unwrapped, _cell_range; and so for y, z), if earlier than
    ``best``: the updated (best, partner, partner's counter).  Each cell's periodic
    image is a shift of the separation, so no grain pair is wrapped one by one.  A
    block inside the grid (most of them) is walked without images: in a dilute gas
    most cells are empty, and stepping through a cell costs about what testing a
    grain does."""
    nx_ = cells.count[0]
    ny_ = cells.count[1]
    wx = _wrapped(cells, box, 0)
    wy = _wrapped(cells, box, 1)
    wz = _wrapped(cells, box, 2)
    if (fx >= 0 and fx + nx <= nx_ and fy >= 0 and fy + ny <= ny_ and fz >= 0
            and fz + nz <= cells.count[2] and not (wx or wy or wz)):
        for z in range(fz, fz + nz):
            for y in range(fy, fy + ny):
                row = (z * ny_ + y) * nx_ + fx
                for c in range(row, row + nx):
                    best, partner, count = _scan_cell(
                        g, cells, box, i, cells.head[c], now, 0.0, 0.0, 0.0, False,
                        False, False, best, partner, count, straight)
        return best, partner, count
    for a in range(nz):
        z, sz = _image(cells, box, fz + a, 2)
        for b in range(ny):
            y, sy = _image(cells, box, fy + b, 1)
            row = (z * ny_ + y) * nx_
            for e in range(nx):
                x, sx = _image(cells, box, fx + e, 0)
                best, partner, count = _scan_cell(
                    g, cells, box, i, cells.head[row + x], now, sx, sy, sz, wx, wy, wz,
                    best, partner, count, straight)
    return best, partner, count


@block_body
def _scan_walls(g, walls, clock, i, now, best, kind, partner):
    """The earliest wall collision (or re-check) of grain i before ``best`` [s from
    now]: the updated (best, kind, partner)."""
    tolerance = clock[TOLERANCE] * g.radii[i]
    for w in range(walls.kind.size):
        t, found = flight.wall_time(
            walls.kind, walls.geometry, walls.base, walls.motion_kind, walls.motion, w,
            now, g.positions[i, 0], g.positions[i, 1], g.positions[i, 2],
            g.velocities[i, 0], g.velocities[i, 1], g.velocities[i, 2], g.gravity[0],
            g.gravity[1], g.gravity[2], g.radii[i], tolerance, best)
        if t < best:
            best = t
            kind = WALL if found == flight.COLLIDE else RECHECK
            partner = w
    return best, kind, partner


@block_body
def predict(g, cal, cells, walls, box, clock, i, now, straight):
    """Find grain i's next events from ``now`` [s] (i must be at ``now``) and put them
    in the calendar: its cell crossing, and the earliest of its collisions with the
    grains of the adjacent cells and with the walls before the crossing (walls are
    looked for again at each crossing)."""
    if not straight and g.fixed[i] != 0:
        _schedule(cal, i, math.inf, NONE, -1, 0, math.inf, -1)
        return
    crossing, face = _crossing(g, cells, box, i, straight)
    fx, nx = _cell_range(cells, box, cells.coords[i, 0], 0)
    fy, ny = _cell_range(cells, box, cells.coords[i, 1], 1)
    fz, nz = _cell_range(cells, box, cells.coords[i, 2], 2)
    best, partner, count = _scan_pairs(g, cells, box, i, now, fx, nx, fy, ny, fz, nz,
                                       math.inf, -1, 0, straight)
    kind = PAIR if partner >= 0 else NONE
    best, kind, partner = _scan_walls(g, walls, clock, i, now, min(best, crossing), kind,
                                      partner) if walls.kind.size else (best, kind, partner)
    _schedule(cal, i, now + best, kind, partner, count, now + crossing, face)


@block_body
def predict_crossed(g, cal, cells, walls, box, clock, i, now, face, straight):
    """Grain i's next events after it crossed ``face`` into its new cell at ``now``: its
    trajectory is unchanged, so the collision predicted before stands (if with a grain:
    the counters judge it when it comes up); only the grains of the layer of cells now
    adjacent beyond the face, the walls and the next crossing are looked at."""
    crossing, next_face = _crossing(g, cells, box, i, straight)
    best = math.inf
    partner = -1
    count = 0
    if cal.kind[i] == PAIR:
        best = cal.next_time[i] - now
        partner = cal.partner[i]
        count = cal.count[i]
    axis = face >> 1
    layer = cells.coords[i, axis] + (1 if face & 1 else -1)
    n = cells.count[axis]
    if box.flag[axis] or 0 <= layer < n:
        fx, nx = _cell_range(cells, box, cells.coords[i, 0], 0)
        fy, ny = _cell_range(cells, box, cells.coords[i, 1], 1)
        fz, nz = _cell_range(cells, box, cells.coords[i, 2], 2)
        first = (layer + n) % n if _wrapped(cells, box, axis) else layer
        if axis == 0:
            fx, nx = first, 1
        elif axis == 1:
            fy, ny = first, 1
        else:
            fz, nz = first, 1
        best, partner, count = _scan_pairs(g, cells, box, i, now, fx, nx, fy, ny, fz, nz,
                                           best, partner, count, straight)
    kind = PAIR if partner >= 0 else NONE
    best, kind, partner = _scan_walls(g, walls, clock, i, now, min(best, crossing), kind,
                                      partner) if walls.kind.size else (best, kind, partner)
    _schedule(cal, i, now + best, kind, partner, count, now + crossing, next_face)


@block_body
def _least_rebound(g, clock, counters, i, mx, my, mz):
    """The smallest speed [m/s] at which grain i leaves a support of infinite mass (a
    wall, a held grain) whose normal (mx, my, mz) points from the support to the grain:
    sqrt(2 |g.m| delta), delta = tolerance x radius, and under the TC model at least
    |g.m| t_c / 2 (a hop lasting t_c) when gravity presses the grain onto it; 0 when it
    pulls the grain away.  A grain coming to rest on a support would otherwise collide
    with it again and again at one instant (its normal speed zero to round-off): it
    hops by delta instead, gaining m |g.m| delta, which is booked as negative normal
    dissipation."""
    press = -(g.gravity[0] * mx + g.gravity[1] * my + g.gravity[2] * mz)
    if press <= 0.0:
        return 0.0
    least = math.sqrt(2.0 * press * clock[TOLERANCE] * g.radii[i])
    if counters[COLLAPSE_MODEL] == TC_MODEL:
        least = max(least, 0.5 * press * clock[CONTACT_DURATION])
    return least


@block_body
def _lift(g, clock, counters, i, mx, my, mz, ux, uy, uz):
    """Make grain i leave a support (normal (mx, my, mz) from the support to it, the
    support's velocity (ux, uy, uz)) at least at _least_rebound; returns the kinetic
    energy this adds in the support's frame [J]."""
    least = _least_rebound(g, clock, counters, i, mx, my, mz)
    v = g.velocities[i]
    out = (v[0] - ux) * mx + (v[1] - uy) * my + (v[2] - uz) * mz
    if out >= least:
        return 0.0
    push = least - out
    v[0] += push * mx
    v[1] += push * my
    v[2] += push * mz
    return 0.5 * g.masses[i] * (least * least - out * out)


@block_body
def _since(g, i, now):
    return now - g.last_collision[i]


@block_body
def _pair_collision(g, tables, clock, counters, box, i, j, now, since, straight):
    """Carry out the collision of grains i and j at ``now`` (both there; their
    orientations left at their last collisions or ``since``, _turn): Pérez Eq. 1-10
    through collision.collision_impulse, energy and virial bookkeeping."""
    _turn(g, i, now, since)
    _turn(g, j, now, since)
    dx, dy, dz, ux, uy, uz = _separation(g, box, i, j, now, straight)
    size = math.sqrt(dx * dx + dy * dy + dz * dz)
    nx = -dx / size              # from a = i to b = j (Pérez Eq. 1)
    ny = -dy / size
    nz = -dz / size
    ri = g.radii[i]
    rj = g.radii[j]
    wi = g.angular_velocities[i]
    wj = g.angular_velocities[j]
    vx, vy, vz = contact_velocity(nx, ny, nz, ux, uy, uz, wi[0], wi[1], wi[2], ri,
                                  0.0, 0.0, 0.0, wj[0], wj[1], wj[2], rj)
    free_i = 1.0 if g.fixed[i] == 0 else 0.0
    free_j = 1.0 if g.fixed[j] == 0 else 0.0
    inv_mi = free_i / g.masses[i]
    inv_mj = free_j / g.masses[j]
    inv_ii = free_i / g.inertias[i]
    inv_ij = free_j / g.inertias[j]
    approach = vx * nx + vy * ny + vz * nz
    e_n, e_s = restitution_now(tables.restitution[g.materials[i], g.materials[j]],
                               clock[TANGENTIAL], counters[COLLAPSE_MODEL], approach,
                               clock[COLLAPSE_SPEED], _since(g, i, now), _since(g, j, now),
                               clock[CONTACT_DURATION])
    jx, jy, jz, dn, ds = collision_impulse(nx, ny, nz, vx, vy, vz, inv_mi + inv_mj,
                                           ri * ri * inv_ii + rj * rj * inv_ij, e_n,
                                           e_s)
    impulse = (jx, jy, jz)
    torque = (ny * jz - nz * jy, nz * jx - nx * jz, nx * jy - ny * jx)    # n x J
    for k in range(3):
        g.velocities[i, k] += impulse[k] * inv_mi
        g.velocities[j, k] -= impulse[k] * inv_mj
        g.angular_velocities[i, k] += ri * torque[k] * inv_ii
        g.angular_velocities[j, k] += rj * torque[k] * inv_ij
    if g.fixed[j] != 0:
        dn -= _lift(g, clock, counters, i, -nx, -ny, -nz, 0.0, 0.0, 0.0)
    elif g.fixed[i] != 0:
        dn -= _lift(g, clock, counters, j, nx, ny, nz, 0.0, 0.0, 0.0)
    clock[DISS_N] += dn
    clock[DISS_T] += ds
    clock[VIRIAL] += dx * jx + dy * jy + dz * jz
    g.collisions[i] += 1
    g.collisions[j] += 1
    g.last_collision[i] = now
    g.last_collision[j] = now
    counters[PAIR_COLLISIONS] += 1


@block_body
def _wall_collision(g, walls, tables, clock, counters, i, w, now, since):
    """Carry out the collision of grain i with wall w at ``now`` (the wall as a grain of
    infinite mass moving at its velocity then; the orientation as in _pair_collision):
    Pérez Eq. 1-10, the wall's impulse and the work it does on the grain."""
    _turn(g, i, now, since)
    x = g.positions[i]
    gap, mx, my, mz, wx, wy, wz = flight.wall_gap(
        walls.kind, walls.geometry, walls.base, walls.motion_kind, walls.motion, w, now,
        x[0], x[1], x[2], g.radii[i])
    nx = -mx                     # from the grain (a) to the wall (b)
    ny = -my
    nz = -mz
    v = g.velocities[i]
    s = g.angular_velocities[i]
    r = g.radii[i]
    vx, vy, vz = contact_velocity(nx, ny, nz, v[0] - wx, v[1] - wy, v[2] - wz, s[0], s[1],
                                  s[2], r, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    approach = vx * nx + vy * ny + vz * nz
    e_n, e_s = restitution_now(tables.restitution[g.materials[i], walls.material[w]],
                               clock[TANGENTIAL], counters[COLLAPSE_MODEL], approach,
                               clock[COLLAPSE_SPEED], _since(g, i, now), math.inf,
                               clock[CONTACT_DURATION])
    inv_m = 1.0 / g.masses[i]
    inv_i = 1.0 / g.inertias[i]
    jx, jy, jz, dn, ds = collision_impulse(nx, ny, nz, vx, vy, vz, inv_m, r * r * inv_i,
                                           e_n, e_s)
    before = 0.5 * (g.masses[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                    + g.inertias[i] * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]))
    impulse = (jx, jy, jz)
    torque = (ny * jz - nz * jy, nz * jx - nx * jz, nx * jy - ny * jx)
    for k in range(3):
        v[k] += impulse[k] * inv_m
        s[k] += r * torque[k] * inv_i
        walls.impulse[w, k] -= impulse[k]
    dn -= _lift(g, clock, counters, i, mx, my, mz, wx, wy, wz)
    after = 0.5 * (g.masses[i] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                   + g.inertias[i] * (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]))
    clock[DISS_N] += dn
    clock[DISS_T] += ds
    clock[WALL_WORK] += after - before + dn + ds
    g.collisions[i] += 1
    g.last_collision[i] = now
    counters[WALL_COLLISIONS] += 1


@block_body
def _cross(g, cells, box, i, face):
    """Move grain i into the cell beyond ``face`` of its own, shifting its coordinate by
    the period when it wraps around a periodic axis."""
    axis = face >> 1
    stride = 1
    for a in range(axis):
        stride *= cells.count[a]
    n = cells.count[axis]
    c = cells.cell[i]
    k = cells.coords[i, axis]
    if face & 1:
        if k == n - 1:
            g.positions[i, axis] -= box.length[axis]
            c -= (n - 1) * stride
            k = 0
        else:
            c += stride
            k += 1
    elif k == 0:
        g.positions[i, axis] += box.length[axis]
        c += (n - 1) * stride
        k = n - 1
    else:
        c -= stride
        k -= 1
    cells.coords[i, axis] = k
    _unlink(cells, i)
    _link(cells, i, c)


@driver
def run_events(g, cal, cells, walls, box, tables, clock, counters, end, straight):
    """Carry out every event before ``end`` [s] (simulated time); returns DONE, or
    COLLAPSED when SAME_TIME_LIMIT events in a row fall at one instant.  The grains are
    left at their own times: ``synchronise`` brings them to ``end``.  ``straight`` (no
    gravity and no held grain) runs a copy of the loop compiled without their terms,
    which gives the same numbers."""
    if straight:
        return _event_loop(g, cal, cells, walls, box, tables, clock, counters, end,
                           np.bool_(True))
    return _event_loop(g, cal, cells, walls, box, tables, clock, counters, end,
                       np.bool_(False))


@block_body
def _event_loop(g, cal, cells, walls, box, tables, clock, counters, end, straight):
    """run_events with ``straight`` a constant."""
    since = clock[TIME]         # every grain is there (engine._prepare)
    last = -math.inf
    while True:
        i = front(cal)
        now = cal.key[0]
        if not now < end:
            return DONE
        if now == last:
            counters[SAME_TIME] += 1
            if counters[SAME_TIME] > SAME_TIME_LIMIT:
                return COLLAPSED
        else:
            counters[SAME_TIME] = 0
            last = now
        clock[TIME] = now
        counters[EVENTS] += 1
        _advance(g, i, now, straight)
        if cal.cross_time[i] <= cal.next_time[i]:
            counters[CROSSINGS] += 1
            face = cal.face[i]
            _cross(g, cells, box, i, face)
            predict_crossed(g, cal, cells, walls, box, clock, i, now, face, straight)
            continue
        kind = cal.kind[i]
        if kind == PAIR:
            j = cal.partner[i]
            if g.collisions[j] != cal.count[i]:
                counters[STALE] += 1
                predict(g, cal, cells, walls, box, clock, i, now, straight)
                continue
            _advance(g, j, now, straight)
            _pair_collision(g, tables, clock, counters, box, i, j, now, since,
                            straight)
            predict(g, cal, cells, walls, box, clock, i, now, straight)
            predict(g, cal, cells, walls, box, clock, j, now, straight)
        elif kind == WALL:
            _wall_collision(g, walls, tables, clock, counters, i, cal.partner[i], now,
                            since)
            predict(g, cal, cells, walls, box, clock, i, now, straight)
        else:
            counters[RECHECKS] += 1
            predict(g, cal, cells, walls, box, clock, i, now, straight)


@driver
def synchronise(g, t, since):
    """Bring every grain to time t [s] (free flight), ``since`` [s] the time of the
    synchronisation before (orientations: _turn)."""
    for i in range(g.radii.size):
        _advance(g, i, t, np.bool_(False))
        _turn(g, i, t, since)


@driver
def bin_grains(g, cells, box):
    """Put every grain into its cell (coordinates along periodic axes wrapped into the
    period first)."""
    cells.head[:] = -1
    for i in range(g.radii.size):
        c = 0
        stride = 1
        for axis in range(3):
            x = g.positions[i, axis]
            if box.flag[axis]:
                x -= box.length[axis] * math.floor((x - box.lo[axis]) / box.length[axis])
                g.positions[i, axis] = x
            k = int(math.floor((x - cells.lo[axis]) / cells.size[axis]))
            k = min(max(k, 0), cells.count[axis] - 1)
            cells.coords[i, axis] = k
            c += k * stride
            stride *= cells.count[axis]
        _link(cells, i, c)


@driver
def _close_pairs(g, cells, box, slack, out_i, out_j, out_gap):
    """Walk the pairs i < j of adjacent cells whose gap |r_i - r_j| - R_i - R_j [m] is at
    most ``slack`` [m] and write the first out_i.size of them; returns how many."""
    found = 0
    nx_ = cells.count[0]
    ny_ = cells.count[1]
    for i in range(g.radii.size):
        fx, nx = _cell_range(cells, box, cells.coords[i, 0], 0)
        fy, ny = _cell_range(cells, box, cells.coords[i, 1], 1)
        fz, nz = _cell_range(cells, box, cells.coords[i, 2], 2)
        for a in range(nz):
            z = _image(cells, box, fz + a, 2)[0]
            for b in range(ny):
                y = _image(cells, box, fy + b, 1)[0]
                for e in range(nx):
                    x = _image(cells, box, fx + e, 0)[0]
                    j = cells.head[(z * ny_ + y) * nx_ + x]
                    while j >= 0:
                        if j > i:
                            dx, dy, dz, ux, uy, uz = _separation(
                                g, box, i, j, g.local_time[i], np.bool_(False))
                            gap = math.sqrt(dx * dx + dy * dy + dz * dz) \
                                - g.radii[i] - g.radii[j]
                            if gap <= slack:
                                if found < out_i.size:
                                    out_i[found] = i
                                    out_j[found] = j
                                    out_gap[found] = gap
                                found += 1
                        j = cells.next[j]
    return found


def close_pairs(g, cells, box, slack):
    """The pairs i < j whose gap is at most ``slack`` [m] (grains binned, all at one
    time): (i, j, gap) arrays."""
    empty = np.zeros(0, np.int64)
    count = _close_pairs(g, cells, box, slack, empty, empty, np.zeros(0))
    i = np.zeros(count, np.int64)
    j = np.zeros(count, np.int64)
    gap = np.zeros(count)
    _close_pairs(g, cells, box, slack, i, j, gap)
    return i, j, gap


@driver
def predict_all(g, cal, cells, walls, box, clock):
    """Predict every grain's next event from the present (all grains at clock[TIME]) and
    build the calendar."""
    now = clock[TIME]
    for i in range(g.radii.size):
        cal.time[i] = math.inf
    build(cal, now)
    for i in range(g.radii.size):
        predict(g, cal, cells, walls, box, clock, i, now, np.bool_(False))
    build(cal, now)     # again, its buckets sized by the events predicted
