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

Convergence, tested after each sweep: the relative change of the impulses
sum |P^k - P^(k-1)| / sum |P^k| and the Signorini violation max |min(W_nn P_n, u_n - b)|
(a complementarity residual in velocity units, zero exactly when Signorini holds) over a
velocity scale V (the largest of |g| dt, |b| and the free normal speeds) must both be
at most ``tolerance``; the residual reported is the larger of the two.
"""
import math

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
def _visit(velocities, angular_velocities, inv_mass, inv_inertia, i, j, ri, rj, normal,
           impulses, k, bound, mu_s, mu_d, wall_velocity, w, compliance):
    """One contact's Gauss-Seidel update: (|dP| [N s], |P| [N s], violation [m/s]);
    ``compliance`` [1/kg] is added to W_nn (a servo wall's g/dt (u . n)^2)."""
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
def servo_velocity(servo, wall_push, wall_velocity, w, dt):
    """The velocity of servo wall w from the force of its contacts F = wall_push / dt
    [N] (core/walls.py's law, here implicit: with this step's impulses),
    v = u clamp(g (F_target - F), -v_max, v_max); servo (W, 10): flag, u (3), F_target
    [N], g [m/(N s)], v_max [m/s], and the velocity the wall was moved at before the
    solve (3, stepping.advance)."""
    speed = min(max(servo[w, 5] * (servo[w, 4] - wall_push[w] / dt), -servo[w, 6]),
                servo[w, 6])
    for d in range(3):
        wall_velocity[w, d] = servo[w, 1 + d] * speed


@kernel
def nlgs(velocities, angular_velocities, inv_mass, inv_inertia, radii, materials, lists,
         wall_material, wall_velocity, active, wall_active, bound, wall_bound, friction,
         tolerance, max_iterations, speed_scale, servo, wall_push, dt):
    """Sweep the active contacts (``active``/``wall_active`` (P,)/(Q,) bool, their normal
    bounds ``bound``/``wall_bound`` [m/s]) until converged (module docstring) or
    ``max_iterations`` sweeps; the velocities and lists' impulses are updated in place.
    friction : (M, M, 2) [-] mu_s, mu_d of each pair of materials (grain or wall).
    servo : (W, 10) per wall (servo_velocity): flag 1 for a servo wall acting this step,
      else 0.  A servo wall joins the solve: its velocity is servo_velocity of the force
      F = sum P . u / dt of its contacts, updated after each of them (wall_push (W,)
      holds sum P . u [N s]), and g/dt (u . n)^2 is added to its contacts' W_nn (the
      wall's response to their impulse).
    Returns (sweeps done, residual)."""
    n = radii.size
    for w in range(servo.shape[0]):
        wall_push[w] = 0.0
    for q in range(lists.wall_start[n]):
        if wall_active[q]:
            w = lists.wall_ids[q]
            wall_push[w] += lists.wall_impulses[q, 0] * servo[w, 1] \
                + lists.wall_impulses[q, 1] * servo[w, 2] \
                + lists.wall_impulses[q, 2] * servo[w, 3]
    for w in range(servo.shape[0]):
        if servo[w, 0] > 0.0:
            servo_velocity(servo, wall_push, wall_velocity, w, dt)
    residual = 0.0
    sweeps = 0
    scale = max(speed_scale, 1e-300)
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
            if servo[w, 0] > 0.0:
                un = lists.wall_normal[q, 0] * servo[w, 1] + lists.wall_normal[q, 1] \
                    * servo[w, 2] + lists.wall_normal[q, 2] * servo[w, 3]
                compliance = servo[w, 5] / dt * un * un
                before = lists.wall_impulses[q, 0] * servo[w, 1] \
                    + lists.wall_impulses[q, 1] * servo[w, 2] \
                    + lists.wall_impulses[q, 2] * servo[w, 3]
            dp, p, v = _visit(velocities, angular_velocities, inv_mass, inv_inertia, i, -1,
                              radii[i], 0.0, lists.wall_normal, lists.wall_impulses, q,
                              wall_bound[q], friction[mi, mw, 0], friction[mi, mw, 1],
                              wall_velocity, w, compliance)
            if servo[w, 0] > 0.0:
                wall_push[w] += lists.wall_impulses[q, 0] * servo[w, 1] \
                    + lists.wall_impulses[q, 1] * servo[w, 2] \
                    + lists.wall_impulses[q, 2] * servo[w, 3] - before
                servo_velocity(servo, wall_push, wall_velocity, w, dt)
            change += dp
            total += p
            violation = max(violation, v)
        sweeps = sweep + 1
        relative = change / total if total > 0.0 else (0.0 if change == 0.0 else 1.0)
        residual = max(relative, violation / scale)
        if residual <= tolerance:
            break
    return sweeps, residual
