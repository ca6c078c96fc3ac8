"""The nonlinear Gauss-Seidel (NLGS) solver of one contact dynamics step (Jean 1999;
Moreau 1994): the contact impulses P [N s] that make the velocities at the end of the
step satisfy, at every contact at once, the laws at the velocity level

  Signorini + Newton:  u_n >= b,  P_n >= 0,  P_n (u_n - b) = 0,
  Coulomb:             |P_t| <= mu_s P_n, u_t = 0 (sticking), or
                       P_t = -mu_d P_n u_t / |u_t| (sliding),

u the relative velocity of the contact points at the end of the step (u_n > 0
separating), b the contact's normal velocity bound (stepping.normal_bound).

Contacts are visited in a fixed order (listed pairs, then wall candidates); each is
solved exactly with the others' impulses fixed, and the grains' velocities are updated
at once (the Gauss-Seidel sweep).  For spheres and disks the branch vectors lie along the
normal, so the local Delassus operator W = H M^-1 H^T of a contact is diagonal in its
frame: W_nn = 1/m_i + 1/m_j, W_tt = W_nn + R_i^2/I_i + R_j^2/I_j (isotropic in the
tangent plane): the local problem has the closed-form solution below (normal
projection, then the Coulomb disk), with no inner iteration.

Rolling resistance (mu_r > 0, the 'constant' law of physics/rolling.py at the velocity
level): a couple impulse C on grain i (-C on grain j) in the tangent plane with
|C| <= mu_r R* P_n, R* = R_i R_j/(R_i + R_j) (R_i against a wall), holding the relative
rolling spin w_r = (w_i - w_j)_t at zero below the bound (no rolling) and opposing it
at the bound, C = -mu_r R* P_n w_r/|w_r|; its operator 1/I_i + 1/I_j is isotropic, so it
is solved in closed form like the friction, in a pass of its own after each sweep of
the impulses (only when some pair of materials has mu_r > 0).

Convergence, tested after each sweep: the relative change of the impulses
sum |P^k - P^(k-1)| / sum |P^k| (a couple counted as |C| / R*) and the Signorini violation max |min(W_nn P_n, u_n - b)|
(a complementarity residual in velocity units, zero exactly when Signorini holds) over a
velocity scale V (the largest of |g| dt, |b| and the free normal speeds) must both be
at most ``tolerance``; the residual reported is the larger of the two.
"""
import math

import numpy as np

from ..._jit import kernel, scalar


@scalar
def contact_velocity(velocities, angular_velocities, i, j, ri, rj, nx, ny, nz, wx, wy, wz):
    """Relative velocity [m/s] of the contact point of grain i against grain j (j < 0:
    against a wall moving at (wx, wy, wz)), normal n from j to i, branches -R_i n and
    +R_j n: (v_i + w_i x a_i) - (v_j + w_j x a_j)."""
    ax, ay, az = -ri * nx, -ri * ny, -ri * nz
    w = angular_velocities
    ux = velocities[i, 0] + w[i, 1] * az - w[i, 2] * ay
    uy = velocities[i, 1] + w[i, 2] * ax - w[i, 0] * az
    uz = velocities[i, 2] + w[i, 0] * ay - w[i, 1] * ax
    if j >= 0:
        bx, by, bz = rj * nx, rj * ny, rj * nz
        ux -= velocities[j, 0] + w[j, 1] * bz - w[j, 2] * by
        uy -= velocities[j, 1] + w[j, 2] * bx - w[j, 0] * bz
        uz -= velocities[j, 2] + w[j, 0] * by - w[j, 1] * bx
    else:
        ux -= wx
        uy -= wy
        uz -= wz
    return ux, uy, uz


@scalar
def apply_impulse(velocities, angular_velocities, inv_mass, inv_inertia, i, j, ri, rj,
                  nx, ny, nz, px, py, pz):
    """Add the impulse P [N s] on grain i (and -P on grain j when j >= 0) at their contact
    point: dv = P/m, dw = (a x P)/I with the branch a (-R_i n for i, +R_j n for j)."""
    ax, ay, az = -ri * nx, -ri * ny, -ri * nz
    velocities[i, 0] += inv_mass[i] * px
    velocities[i, 1] += inv_mass[i] * py
    velocities[i, 2] += inv_mass[i] * pz
    angular_velocities[i, 0] += inv_inertia[i] * (ay * pz - az * py)
    angular_velocities[i, 1] += inv_inertia[i] * (az * px - ax * pz)
    angular_velocities[i, 2] += inv_inertia[i] * (ax * py - ay * px)
    if j >= 0:
        bx, by, bz = rj * nx, rj * ny, rj * nz
        velocities[j, 0] -= inv_mass[j] * px
        velocities[j, 1] -= inv_mass[j] * py
        velocities[j, 2] -= inv_mass[j] * pz
        angular_velocities[j, 0] -= inv_inertia[j] * (by * pz - bz * py)
        angular_velocities[j, 1] -= inv_inertia[j] * (bz * px - bx * pz)
        angular_velocities[j, 2] -= inv_inertia[j] * (bx * py - by * px)


@scalar
def local_solve(ux, uy, uz, nx, ny, nz, px, py, pz, bound, wnn, wtt, mu_s, mu_d):
    """The exact solution of one contact's laws with the others' impulses fixed: the
    new impulse (3 components [N s]) from the present one P and relative velocity u.

    Normal: P_n = max(0, P_n - (u_n - b)/W_nn).  Tangential: w = u_t - W_tt P_t is the
    sliding velocity without this contact's friction; the sticking impulse -w/W_tt is
    kept when within mu_s P_n, else P_t = -mu_d P_n w/|w| (sliding, opposite the
    sliding velocity, which is then along w since W_tt is isotropic)."""
    un = ux * nx + uy * ny + uz * nz
    pn = px * nx + py * ny + pz * nz
    pn_new = max(0.0, pn - (un - bound) / wnn)
    tx, ty, tz = px - pn * nx, py - pn * ny, pz - pn * nz
    qx, qy, qz = 0.0, 0.0, 0.0
    if wtt > 0.0 and pn_new > 0.0:
        wx = ux - un * nx - wtt * tx
        wy = uy - un * ny - wtt * ty
        wz = uz - un * nz - wtt * tz
        speed = math.sqrt(wx * wx + wy * wy + wz * wz)
        if speed <= wtt * mu_s * pn_new:
            qx, qy, qz = -wx / wtt, -wy / wtt, -wz / wtt
        else:
            scale = -mu_d * pn_new / speed
            qx, qy, qz = scale * wx, scale * wy, scale * wz
    return pn_new * nx + qx, pn_new * ny + qy, pn_new * nz + qz


@scalar
def relative_spin(angular_velocities, i, j):
    """w_i - w_j [rad/s] (w_i alone against a wall, j < 0)."""
    w = angular_velocities
    if j < 0:
        return w[i, 0], w[i, 1], w[i, 2]
    return w[i, 0] - w[j, 0], w[i, 1] - w[j, 1], w[i, 2] - w[j, 2]


@scalar
def arm(ri, rj):
    """The rolling arm R* [m]: R_i R_j / (R_i + R_j), R_i against a wall (r_j = 0)."""
    return ri if rj == 0.0 else ri * rj / (ri + rj)


@scalar
def apply_couple(angular_velocities, inv_inertia, i, j, cx, cy, cz):
    """Add the couple impulse C [N m s] on grain i (-C on grain j when j >= 0):
    dw = C / I."""
    w = angular_velocities
    w[i, 0] += inv_inertia[i] * cx
    w[i, 1] += inv_inertia[i] * cy
    w[i, 2] += inv_inertia[i] * cz
    if j >= 0:
        w[j, 0] -= inv_inertia[j] * cx
        w[j, 1] -= inv_inertia[j] * cy
        w[j, 2] -= inv_inertia[j] * cz


@scalar
def _roll(angular_velocities, inv_inertia, i, j, nx, ny, nz, impulses, k, limit):
    """The rolling couple impulse of contact k (module docstring) with the others fixed,
    |C| <= ``limit`` [N m s]; the spins updated at once.  Returns (|dC|, |C|) [N m s]."""
    wrr = inv_inertia[i] + (inv_inertia[j] if j >= 0 else 0.0)
    rx, ry, rz = relative_spin(angular_velocities, i, j)
    if wrr == 0.0:
        return 0.0, 0.0
    cx, cy, cz = impulses[k, 3], impulses[k, 4], impulses[k, 5]
    rn = rx * nx + ry * ny + rz * nz
    cn = cx * nx + cy * ny + cz * nz
    sx = rx - rn * nx - wrr * (cx - cn * nx)      # rolling spin without this couple
    sy = ry - rn * ny - wrr * (cy - cn * ny)
    sz = rz - rn * nz - wrr * (cz - cn * nz)
    speed = math.sqrt(sx * sx + sy * sy + sz * sz)
    scale = -1.0 / wrr if speed <= wrr * limit else -limit / speed
    qx, qy, qz = scale * sx, scale * sy, scale * sz
    impulses[k, 3], impulses[k, 4], impulses[k, 5] = qx, qy, qz
    dx, dy, dz = qx - cx, qy - cy, qz - cz
    apply_couple(angular_velocities, inv_inertia, i, j, dx, dy, dz)
    return math.sqrt(dx * dx + dy * dy + dz * dz), math.sqrt(qx * qx + qy * qy + qz * qz)


@scalar
def _roll_contact(angular_velocities, inv_inertia, i, j, ri, rj, normal, impulses, k,
                  mu_r):
    """The rolling update of contact k (_roll) with its bound mu_r R* P_n from the
    contact's present normal impulse: (|dC| / R*, |C| / R*) [N s]."""
    nx, ny, nz = normal[k, 0], normal[k, 1], normal[k, 2]
    pn = max(impulses[k, 0] * nx + impulses[k, 1] * ny + impulses[k, 2] * nz, 0.0)
    r_eff = arm(ri, rj)
    dc, c = _roll(angular_velocities, inv_inertia, i, j, nx, ny, nz, impulses, k,
                  mu_r * r_eff * pn)
    return dc / r_eff, c / r_eff


@scalar
def _visit(velocities, angular_velocities, inv_mass, inv_inertia, i, j, ri, rj, normal,
           impulses, k, bound, mu_s, mu_d, wall_velocity, w, compliance):
    """One contact's Gauss-Seidel update: (|dP| [N s], |P| [N s], violation [m/s]);
    ``compliance`` [1/kg] is added to W_nn (a solved wall's response (u . n)^2)."""
    nx, ny, nz = normal[k, 0], normal[k, 1], normal[k, 2]
    vx, vy, vz = 0.0, 0.0, 0.0
    wnn = inv_mass[i] + compliance
    wtt = wnn + ri * ri * inv_inertia[i]
    if j >= 0:
        wnn += inv_mass[j]
        wtt += inv_mass[j] + rj * rj * inv_inertia[j]
    else:
        vx, vy, vz = wall_velocity[w, 0], wall_velocity[w, 1], wall_velocity[w, 2]
    if wnn == 0.0:
        return 0.0, 0.0, 0.0
    ux, uy, uz = contact_velocity(velocities, angular_velocities, i, j, ri, rj, nx, ny, nz,
                                  vx, vy, vz)
    px, py, pz = impulses[k, 0], impulses[k, 1], impulses[k, 2]
    un = ux * nx + uy * ny + uz * nz
    violation = abs(min(wnn * (px * nx + py * ny + pz * nz), un - bound))
    qx, qy, qz = local_solve(ux, uy, uz, nx, ny, nz, px, py, pz, bound, wnn, wtt, mu_s, mu_d)
    impulses[k, 0], impulses[k, 1], impulses[k, 2] = qx, qy, qz
    dx, dy, dz = qx - px, qy - py, qz - pz
    apply_impulse(velocities, angular_velocities, inv_mass, inv_inertia, i, j, ri, rj,
                  nx, ny, nz, dx, dy, dz)
    return math.sqrt(dx * dx + dy * dy + dz * dz), math.sqrt(qx * qx + qy * qy + qz * qz), \
        violation


@scalar
def solved_velocity(solved, wall_push, wall_velocity, w, dt):
    """The velocity of wall w solved with the impulses, from wall_push (W,) [N s], the
    sum P . u of its contacts' impulses on the grains:
      servo (flag 1): v = u clamp(g (F_target - wall_push / dt), -v_max, v_max)
        (core/walls.py's law, here implicit: with this step's impulses);
      piston (flag 2): v = u (s_free - wall_push / M), the wall's momentum balance over
        the step, s_free its speed after the applied force alone.
    solved (W, 10): flag (0 none, 1 servo, 2 piston), u (3), then F_target [N], gain g
    [m/(N s)], v_max [m/s] (servo) or s_free [m/s], 1/M [1/kg], 0 (piston), and the
    velocity the wall was moved at before the solve (3, stepping.advance)."""
    if solved[w, 0] == 1.0:
        speed = min(max(solved[w, 5] * (solved[w, 4] - wall_push[w] / dt), -solved[w, 6]),
                    solved[w, 6])
    else:
        speed = solved[w, 4] - solved[w, 5] * wall_push[w]
    for d in range(3):
        wall_velocity[w, d] = solved[w, 1 + d] * speed


@scalar
def wall_response(solved, w, dt):
    """d(speed)/d(P . u) of a solved wall w [1/kg] (solved_velocity): g/dt for a servo,
    1/M for a piston; 0 for any other wall."""
    if solved[w, 0] == 1.0:
        return solved[w, 5] / dt
    if solved[w, 0] == 2.0:
        return solved[w, 5]
    return 0.0


@kernel
def nlgs(velocities, angular_velocities, inv_mass, inv_inertia, radii, materials, lists,
         wall_material, wall_velocity, active, wall_active, bound, wall_bound, friction,
         rolling, tolerance, max_iterations, speed_scale, solved, wall_push, dt):
    """Sweep the active contacts (``active``/``wall_active`` (P,)/(Q,) bool, their normal
    bounds ``bound``/``wall_bound`` [m/s]) until converged (module docstring) or
    ``max_iterations`` sweeps; the velocities and lists' impulses are updated in place.
    friction : (M, M, 2) [-] mu_s, mu_d of each pair of materials (grain or wall);
    rolling : (M, M) [-] their mu_r.
    solved : (W, 10) per wall (solved_velocity): flag 1 for a servo, 2 for a piston
      acting this step, else 0.  Such a wall joins the solve: its velocity is
      solved_velocity of sum P . u of its contacts' impulses (wall_push (W,) [N s]),
      updated after each of them, and wall_response (u . n)^2 is added to its contacts'
      W_nn (the wall's response to their impulse).
    Returns (sweeps done, residual)."""
    n = radii.size
    for w in range(solved.shape[0]):
        wall_push[w] = 0.0
    for q in range(lists.wall_start[n]):
        if wall_active[q]:
            w = lists.wall_ids[q]
            wall_push[w] += lists.wall_impulses[q, 0] * solved[w, 1] \
                + lists.wall_impulses[q, 1] * solved[w, 2] \
                + lists.wall_impulses[q, 2] * solved[w, 3]
    for w in range(solved.shape[0]):
        if solved[w, 0] > 0.0:
            solved_velocity(solved, wall_push, wall_velocity, w, dt)
    residual = 0.0
    sweeps = 0
    scale = max(speed_scale, 1e-300)
    rolling_on = rolling.max() > 0.0
    for sweep in range(max_iterations):
        change = 0.0
        total = 0.0
        violation = 0.0
        for k in range(lists.start[n]):
            if not active[k]:
                continue
            i = lists.owner[k]
            j = lists.partners[k]
            mi, mj = materials[i], materials[j]
            dp, p, v = _visit(velocities, angular_velocities, inv_mass, inv_inertia, i, j,
                              radii[i], radii[j], lists.normal, lists.impulses, k, bound[k],
                              friction[mi, mj, 0], friction[mi, mj, 1], wall_velocity, 0,
                              0.0)
            change += dp
            total += p
            violation = max(violation, v)
        for q in range(lists.wall_start[n]):
            if not wall_active[q]:
                continue
            i = lists.wall_owner[q]
            w = lists.wall_ids[q]
            mi, mw = materials[i], wall_material[w]
            compliance = 0.0
            before = 0.0
            if solved[w, 0] > 0.0:
                un = lists.wall_normal[q, 0] * solved[w, 1] + lists.wall_normal[q, 1] \
                    * solved[w, 2] + lists.wall_normal[q, 2] * solved[w, 3]
                compliance = wall_response(solved, w, dt) * un * un
                before = lists.wall_impulses[q, 0] * solved[w, 1] \
                    + lists.wall_impulses[q, 1] * solved[w, 2] \
                    + lists.wall_impulses[q, 2] * solved[w, 3]
            dp, p, v = _visit(velocities, angular_velocities, inv_mass, inv_inertia, i, -1,
                              radii[i], 0.0, lists.wall_normal, lists.wall_impulses, q,
                              wall_bound[q], friction[mi, mw, 0], friction[mi, mw, 1],
                              wall_velocity, w, compliance)
            if solved[w, 0] > 0.0:
                wall_push[w] += lists.wall_impulses[q, 0] * solved[w, 1] \
                    + lists.wall_impulses[q, 1] * solved[w, 2] \
                    + lists.wall_impulses[q, 2] * solved[w, 3] - before
                solved_velocity(solved, wall_push, wall_velocity, w, dt)
            change += dp
            total += p
            violation = max(violation, v)
        # rolling resistance in a pass of its own: inside the visits above, its code
        # slowed every sweep by half even with no mu_r (200 disks: 16.5 -> 25 us a sweep)
        if rolling_on:
            for k in range(lists.start[n] + lists.wall_start[n]):
                wall = k >= lists.start[n]
                q = k - lists.start[n] if wall else k
                if not (wall_active[q] if wall else active[q]):
                    continue
                if wall:
                    i, j, rj = lists.wall_owner[q], np.int64(-1), 0.0
                    mu_r = rolling[materials[i], wall_material[lists.wall_ids[q]]]
                    normal, impulses = lists.wall_normal, lists.wall_impulses
                else:
                    i, j = lists.owner[q], np.int64(lists.partners[q])
                    rj = radii[j]
                    mu_r = rolling[materials[i], materials[j]]
                    normal, impulses = lists.normal, lists.impulses
                if mu_r > 0.0:
                    dc, c = _roll_contact(angular_velocities, inv_inertia, i, j, radii[i],
                                          rj, normal, impulses, q, mu_r)
                    change += dc
                    total += c
        sweeps = sweep + 1
        relative = change / total if total > 0.0 else (0.0 if change == 0.0 else 1.0)
        residual = max(relative, violation / scale)
        if residual <= tolerance:
            break
    return sweeps, residual
