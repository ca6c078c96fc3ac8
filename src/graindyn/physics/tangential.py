"""Tangential (friction) laws.  Forces [N] act on grain i; v_t [m/s] is the tangential
velocity of i relative to j at the contact point; each returns the force and the
energy [J] dissipated during the step dt [s].  History values of a contact sit in
history[hrow(k, h:h + n)], h the tangential offset of the model (registry.history_layout).
The same functions serve disks: in 2D v_t and the spring stay in the plane, and the
springs of cundall_strack, mindlin and karrech take their scalar 2D form
(tangential_planar_spring_force, chosen by physics.contact from the model's planar flag).
"""
import math

from .._jit import scalar
from .indexing import hrow


@scalar
def tangential_coulomb_force(mu, fn, vtx, vty, vtz, dt):
    """Pure sliding friction f_t = -mu f_n v_t/|v_t| (Perez Eq. 19); zero when v_t = 0."""
    speed = math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    if speed == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    s = -mu * fn / speed
    return s * vtx, s * vty, s * vtz, mu * fn * speed * dt


@scalar
def tangential_spring_force(kt, eta_t, mu, fn, cap, nx, ny, nz, vtx, vty, vtz,
                            history, k, h, dt):
    """Capped tangential spring with dashpot: Cundall-Strack (Perez Eq. 20-23) in 3D.

    history[hrow(k, h:h+3)] holds the spring elongation zeta [m].  Each step zeta is first
    rotated into the current tangent plane keeping its length, then grows by v_t dt
    (Eq. 20).  ``cap`` says what mu f_n limits:
    0: the trial force f = -kt zeta - eta_t v_t (Eq. 22); when capped zeta is reset so
       that spring and dashpot give exactly the capped force: the elongation stops
       growing while the contact slides (Eq. 23).  (When the dashpot alone exceeds
       the cap this books a negative loss for the step, as LAMMPS does.)
    1: the spring force -kt zeta only, the dashpot is added to it (Karrech Eq. 7);
    2: the spring force only, and the dashpot acts only below the cap (Ai et al. 2011
       EPSD: no damping at full mobilisation).
    With 1 and 2 the step never books a negative loss.
    kt [N/m], eta_t [kg/s].  Returns f_t (3) and the energy dissipated in the step,
    the work -f_t.v_t dt not stored in the spring.
    """
    zx = history[hrow(k, h)]
    zy = history[hrow(k, h + 1)]
    zz = history[hrow(k, h + 2)]
    old = zx * zx + zy * zy + zz * zz
    if old > 0.0:
        zn = zx * nx + zy * ny + zz * nz
        zx -= zn * nx
        zy -= zn * ny
        zz -= zn * nz
        new = zx * zx + zy * zy + zz * zz
        if new > 0.0:
            scale = math.sqrt(old / new)
            zx *= scale
            zy *= scale
            zz *= scale
    energy_before = 0.5 * kt * old
    zx += vtx * dt
    zy += vty * dt
    zz += vtz * dt
    # the part of the force that is capped: spring + dashpot, or the spring alone
    viscous = eta_t if cap == 0 else 0.0
    fx = -kt * zx - viscous * vtx
    fy = -kt * zy - viscous * vty
    fz = -kt * zz - viscous * vtz
    f2 = fx * fx + fy * fy + fz * fz
    limit = mu * fn
    capped = f2 > limit * limit
    if capped:
        s = limit / math.sqrt(f2)
        fx *= s
        fy *= s
        fz *= s
        if kt > 0.0:
            compliance = -1.0 / kt       # one division, not three
            zx = (fx + viscous * vtx) * compliance
            zy = (fy + viscous * vty) * compliance
            zz = (fz + viscous * vtz) * compliance
        else:
            zx = 0.0
            zy = 0.0
            zz = 0.0
    if cap == 1 or (cap == 2 and not capped):
        fx -= eta_t * vtx
        fy -= eta_t * vty
        fz -= eta_t * vtz
    history[hrow(k, h)] = zx
    history[hrow(k, h + 1)] = zy
    history[hrow(k, h + 2)] = zz
    energy_after = 0.5 * kt * (zx * zx + zy * zy + zz * zz)
    work = -(fx * vtx + fy * vty + fz * vtz) * dt
    return fx, fy, fz, work - (energy_after - energy_before)


@scalar
def tangential_planar_spring_force(kt, eta_t, mu, fn, cap, nx, ny, vtx, vty, history, k, h,
                                   dt):
    """The capped spring with dashpot of tangential_spring_force for disks in the x-y
    plane, in Perez's 2D form (Eq. 20-23): the elongation is the scalar
    zeta = int v_s dt along s = z x n = (-n_y, n_x), which turns with the contact, so
    nothing has to be rotated.  The same physics as the vector form, whose elongation
    stays along s with its length kept as s turns, without its square root and
    division per contact.  history[hrow(k, h)] holds zeta [m] (h + 1 and h + 2, the
    vector form's other components, stay zero, so that the spring's energy
    kt |zeta|^2 / 2 reads the same, tangential_spring_energy); ``cap`` as in
    tangential_spring_force.  v_t (vtx, vty) [m/s] lies along s.  Returns f_t (3, its
    z component zero) [N] and the energy dissipated in the step [J]."""
    sx = -ny
    sy = nx
    slip = vtx * sx + vty * sy
    zeta = history[hrow(k, h)]
    energy_before = 0.5 * kt * zeta * zeta
    zeta += slip * dt
    viscous = eta_t if cap == 0 else 0.0
    f = -kt * zeta - viscous * slip
    limit = mu * fn
    capped = abs(f) > limit
    if capped:
        f = math.copysign(limit, f)
        zeta = (f + viscous * slip) * (-1.0 / kt) if kt > 0.0 else 0.0
    if cap == 1 or (cap == 2 and not capped):
        f -= eta_t * slip
    history[hrow(k, h)] = zeta
    work = -f * slip * dt
    return f * sx, f * sy, 0.0, work - (0.5 * kt * zeta * zeta - energy_before)


@scalar
def tangential_mindlin_stiffness(shear_eff, contact_radius):
    """Mindlin no-slip stiffness kt = 8 G* a [N/m], a = sqrt(R* xi) (Karrech Eq. 6)."""
    return 8.0 * shear_eff * contact_radius


@scalar
def tangential_spring_energy(kt, history, k, h):
    """Energy kt |zeta|^2/2 [J] stored in the tangential spring history[hrow(k, h:h+3)]."""
    zx = history[hrow(k, h)]
    zy = history[hrow(k, h + 1)]
    zz = history[hrow(k, h + 2)]
    return 0.5 * kt * (zx * zx + zy * zy + zz * zz)


@scalar
def tangential_mindlin_rescale(shear_eff, contact_radius, history, k, h):
    """Elata & Berryman 1996 / Roux correction of the Mindlin spring (Karrech Sec. 2:
    "when F_n decreases by dF_n, the tangential force at F_n - dF_n is assigned to
    F_t"), before the step's increment.

    history[hrow(k, h:h+3)] is the elongation zeta, history[hrow(k, h+3)] the contact radius a of
    the previous evaluation.  The stiffness kt = 8 G* a follows a.  When a grows
    (loading) zeta shrinks by a_old/a so the force kt zeta is kept: new stiffness acts
    only on new increments (dF_t = kt d(delta_t)).  When a shrinks (unloading) zeta is
    kept, so the force scales down with kt, to the value it has under the smaller
    normal force.  The stored energy kt |zeta|^2/2 never grows by either move.
    Returns (kt [N/m] and the energy [J] the move released, counted as dissipated).
    """
    a_old = history[hrow(k, h + 3)]
    zx = history[hrow(k, h)]
    zy = history[hrow(k, h + 1)]
    zz = history[hrow(k, h + 2)]
    kt = tangential_mindlin_stiffness(shear_eff, contact_radius)
    z2 = zx * zx + zy * zy + zz * zz
    # without branches (selects, every store made), so that the CPU's law loop can
    # evaluate contacts in SIMD lanes (engines/soft/law_loop.py); the values are those of the
    # branching form: s = 1 leaves zeta as it is
    grow = (contact_radius > a_old) & (a_old > 0.0)
    s = a_old / contact_radius if grow else 1.0
    history[hrow(k, h)] = zx * s
    history[hrow(k, h + 1)] = zy * s
    history[hrow(k, h + 2)] = zz * s
    history[hrow(k, h + 3)] = contact_radius
    # kt_old |zeta|^2/2 - kt s^2 |zeta|^2/2 = 4 G* a_old |zeta|^2 (1 - s) when a grows
    lost = 4.0 * shear_eff * a_old * z2 * (1.0 - s) if grow else \
        4.0 * shear_eff * (a_old - contact_radius) * z2
    return kt, lost if a_old > 0.0 else 0.0


@scalar
def tangential_oquendo_force(kt, eta_t, mu_k, mu_s, threshold, fresh, fn, nx, ny, nz, vtx,
                             vty, vtz, history, k, h, dt):
    """Oquendo Eq. 4-6 and 10: the regime follows the slip velocity v_t at the contact
    point (Eq. 4; the contact point of Eq. 3 is used by the caller).

    Sliding: f = -mu_k |f_n| v_t/|v_t| (Eq. 5).  A new contact (``fresh``) slides when
    |v_t| > threshold; a sliding one keeps sliding while |v_t| > threshold and v_t
    has not turned back against its previous direction (history[hrow(k, h+4:h+7)] holds
    the previous slip velocity while sliding, zero otherwise: in one step the slip
    may jump across the threshold band).  Otherwise the grains stick or roll and
    static friction holds the contact point (Eq. 10).  Reading of Eq. 10: the force
    "-F^t" that cancels the tangential pull is found, as in Cundall & Strack, by a
    stiff spring kt (history[hrow(k, h:h+3)]) with dashpot eta_t that grows from zero with
    the contact-point displacement, and holds while spring + dashpot stay below
    mu_s |f_n|.  When they would exceed it the contact starts to slide: the sliding
    force applies from that step on and the spring is emptied (its energy counts as
    dissipated).  Once stuck, a contact stays stuck until that happens, even if the
    contact point moves faster than the threshold while the spring catches it.
    Returns f_t (3), the energy dissipated [J], and 1.0 when sliding (else 0.0).

    Written without branches (both regimes evaluated, the outcome chosen by selects,
    every history value stored), so that the CPU's law loop evaluates contacts in SIMD
    lanes (engines/soft/law_loop.py); the numbers are those of the branching form:
    the spring's update, made for a sliding contact too, is then replaced by zeros.
    """
    px = history[hrow(k, h + 4)]
    py = history[hrow(k, h + 5)]
    pz = history[hrow(k, h + 6)]
    speed = math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    sliding = (speed > threshold) & (fresh | (px * vtx + py * vty + pz * vtz > 0.0))
    lost = tangential_spring_energy(kt, history, k, h)
    sx, sy, sz, spent = tangential_spring_force(kt, eta_t, mu_s, fn, 2, nx, ny, nz, vtx, vty,
                                                vtz, history, k, h, dt)
    # static friction exceeded while the contact point moves: slide from this step
    sliding = sliding | ((speed > 0.0) & (fn > 0.0)
                         & (sx * sx + sy * sy + sz * sz
                            >= (1.0 - 1e-12) * ((mu_s * fn) * (mu_s * fn))))
    # (each store written out: a loop over the three would be an inner loop, and the
    # vectorizer takes only innermost loops)
    history[hrow(k, h)] = 0.0 if sliding else history[hrow(k, h)]
    history[hrow(k, h + 1)] = 0.0 if sliding else history[hrow(k, h + 1)]
    history[hrow(k, h + 2)] = 0.0 if sliding else history[hrow(k, h + 2)]
    history[hrow(k, h + 4)] = vtx if sliding else 0.0
    history[hrow(k, h + 5)] = vty if sliding else 0.0
    history[hrow(k, h + 6)] = vtz if sliding else 0.0
    cx, cy, cz, work = tangential_coulomb_force(mu_k, fn, vtx, vty, vtz, dt)
    if sliding:
        return cx, cy, cz, work + lost, 1.0
    return sx, sy, sz, spent, 0.0


@scalar
def tangential_oquendo_literal_force(mu_k, mu_s, tan_theta_r, threshold, inertia_ratio,
                                     fn, r_roll, m_eff, nx, ny, nz, vtx, vty, vtz,
                                     wrx, wry, wrz, history, k, h, dt):
    """Oquendo Eq. 4-10 read literally: three regimes that exclude each other.

    Sliding (|v_t| > threshold): f = -mu_k |f_n| v_t/|v_t| (Eq. 5).  In one step the
    slip of a sliding contact may jump across zero and beyond the threshold: it has
    passed through rest, so the contact is caught by static friction (below) until
    |v_t| is back under the threshold (history[hrow(k, h:h+3)] holds the slip of the
    last sliding step, zero otherwise; history[hrow(k, h+3)] is 2 while catching).
    Rolling (not sliding, |v_r| > threshold, v_r = R'_ij w_r x n, Eq. 7): the force of
    Eq. 8, f = -|f_n| tan(theta_r)/(1 + beta) t with t = v_r/|v_r| and
    beta = I/(m R^2) = ``inertia_ratio`` (2/5 spheres, 1/2 disks), at the contact point,
    and the caller adds the couple M = -R'_ij |f_n| tan(theta_r) w_r/|w_r|
    (physics.rolling.rolling_constant_torque): with the lever torque of f the total
    torque on a grain rolling on a plane is Eq. 9.  Nothing else resists the slip in
    this regime.
    Static (neither): Eq. 10, f = -F^t while |F^t| < mu_s |f_n|, F^t the tangential
    pull.  The law has no memory of a displacement, so the pull is read from the slip
    it produced in the last step: F^t = m_t v_t/dt, m_t = m* beta/(1 + beta) the mass
    of the contact point's tangential motion (translation and rotation of both
    grains), dt the time the evaluation stands for (the kick that follows it).  Half of
    it is applied, f = -m_t v_t/(2 dt): the full amount, evaluated
    with a predicted velocity, overshoots every step and flips the slip's sign.  A
    steady pull F is then held with a creep of the contact point of 2 F dt/m_t, and a
    contact whose creep passes the threshold slides.  When |f| would reach
    mu_s |f_n| the contact slides from this step on.
    w_r [rad/s]: the rolling part of w_i - w_j (tangent-plane component).
    Returns f_t (3) [N], the energy dissipated [J] (-f.v_t dt; the couple's is the
    caller's) and the regime: 1.0 sliding, 2.0 rolling, 0.0 static.
    """
    px = history[hrow(k, h)]
    py = history[hrow(k, h + 1)]
    pz = history[hrow(k, h + 2)]
    catching = history[hrow(k, h + 3)] == 2.0
    speed = math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    turned = px * vtx + py * vty + pz * vtz < 0.0
    fast = speed > threshold
    sliding = fast & (not catching) & (not turned)
    catching = fast & (not sliding)
    # the three regimes evaluated for every contact and chosen by selects, every history
    # value stored (SIMD lanes, as tangential_oquendo_force); the numbers are those of
    # the branching form
    # rolling velocity R'_ij w_r x n (Eq. 7)
    rx = r_roll * (wry * nz - wrz * ny)
    ry = r_roll * (wrz * nx - wrx * nz)
    rz = r_roll * (wrx * ny - wry * nx)
    rolling = math.sqrt(rx * rx + ry * ry + rz * rz)
    rolls = (not sliding) & (rolling > threshold) & (not catching)
    # static: an evaluation that advances no time (dt = 0) has no pull to read
    static = (not sliding) & (not rolls) & (dt > 0.0)
    s = -fn * tan_theta_r / ((1.0 + inertia_ratio) * rolling)
    c = -0.5 * m_eff * inertia_ratio / ((1.0 + inertia_ratio) * dt)
    fx = s * rx if rolls else (c * vtx if static else 0.0)
    fy = s * ry if rolls else (c * vty if static else 0.0)
    fz = s * rz if rolls else (c * vtz if static else 0.0)
    sliding = sliding | (static & (fn > 0.0) & (speed > 0.0)
                         & (fx * fx + fy * fy + fz * fz >= (mu_s * fn) * (mu_s * fn)))
    history[hrow(k, h)] = vtx if sliding else 0.0
    history[hrow(k, h + 1)] = vty if sliding else 0.0
    history[hrow(k, h + 2)] = vtz if sliding else 0.0
    history[hrow(k, h + 3)] = 2.0 if catching & (not sliding) else 1.0
    cx, cy, cz, work = tangential_coulomb_force(mu_k, fn, vtx, vty, vtz, dt)
    if sliding:
        return cx, cy, cz, work, 1.0
    return fx, fy, fz, -(fx * vtx + fy * vty + fz * vtz) * dt, 2.0 if rolls else 0.0
