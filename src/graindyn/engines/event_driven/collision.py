"""The collision rule of hard rough spheres and disks (Pérez Sec. 2, Eq. 1-10), written
with inverse masses so that one function serves grain pairs, held grains and walls.

Pérez's rule: with n the unit normal from grain a to grain b (Eq. 1) and the relative
velocity of the contact points v_ab = v_a - v_b + (R_a w_a + R_b w_b) x n (Eq. 2), split
into v_n = (v_ab . n) n and v_s = v_ab - v_n (Eq. 3-4), the collision maps

    v_n' = -e_n v_n  (Eq. 5),     v_s' = e_s v_s  (Eq. 6),

e_n in [0, 1], e_s in [-1, 1]: e_s = +1 leaves the tangential velocity as it was (smooth
grains, no tangential impulse: Eq. 8's (e_s - 1) vanishes), e_s = -1 reverses it
(perfectly rough grains, elastic in the tangential direction too), e_s = 0 stops it.
Eq. 7-10 give the velocities and spins that conserve linear momentum and angular
momentum about the contact point.  The same rule is the impulse J on grain a,

    J = -(1 + e_n) mu_n v_n + (e_s - 1) mu_s v_s,
    1/mu_n = 1/m_a + 1/m_b,   1/mu_s = (1/m_a + R_a^2/I_a) + (1/m_b + R_b^2/I_b),

v_a' = v_a + J/m_a, w_a' = w_a + R_a n x J / I_a, v_b' = v_b - J/m_b,
w_b' = w_b + R_b n x J / I_b: Eq. 8-10 multiplied out (m_a m_b D = J, and
m_a m_b / T = mu_s of Eq. 7).  An infinite mass (a held grain, a wall) has 1/m = R^2/I
= 0, which is the limit of Eq. 7-10.  The normal and tangential parts decouple, so the
kinetic energy lost splits exactly into

    dE_n = mu_n |v_n|^2 (1 - e_n^2) / 2,   dE_s = mu_s |v_s|^2 (1 - e_s^2) / 2   [J].

Inelastic collapse (Pérez after Eq. 6: "let e_n tend to 1 if very small velocities
appear"): ``restitution_now`` gives the restitutions of one collision under the models
of ``COLLAPSE``.
"""
from ..._jit import scalar

# the inelastic-collapse treatments (engine setting ``collapse``)
NONE, SPEED, TC = 0, 1, 2
COLLAPSE = {"none": NONE, "speed": SPEED, "tc": TC}
# under TC, collisions closer in time than this fraction of t_c count as simultaneous
SAME_INSTANT = 1e-9


@scalar
def restitution_now(e0, es0, model, approach_speed, collapse_speed, since_a, since_b,
                    contact_duration):
    """The normal and tangential restitutions (e_n, e_s) [-] of one collision of base
    restitutions ``e0`` and ``es0``.

    model NONE: (e0, es0).  SPEED: e_n = 1 - (1 - e0) (u / u0)^(3/4) below u0 =
    ``collapse_speed`` [m/s] and e0 above it, u = ``approach_speed`` [m/s] (the
    impact-speed dependence Bizon et al. 1998 and McNamara & Falcon 2004 use for
    vibrated beds): e_n tends to 1 as u tends to 0, as Perez asks; e_s = es0, but 1
    (smooth) for a collision at the very instant of the previous one of either grain
    (``since_a`` or ``since_b`` zero), which ends the one-instant cascade of a rough
    grain wedged between a moving wall and another (below).
    TC (Luding & McNamara 1998): when either grain collided less than
    ``contact_duration`` t_c [s] before (``since_a``, ``since_b`` [s]: the times since
    their last collisions), the normal part is elastic, e_n = 1, and the tangential
    part keeps es0; a collision at the same instant as the previous one of either
    grain (within SAME_INSTANT t_c) is smooth as well, e_s = 1.  A rough grain wedged
    between a moving floor and a side wall otherwise trades its spin and its velocity
    at each impact and hits the two walls in turn forever at one instant; any wider
    smooth window would leave the spin of hopping grains undamped, and a bed would
    never come to rest.  (e0, es0) otherwise."""
    if model == SPEED:
        e_s = 1.0 if min(since_a, since_b) == 0.0 else es0
        if approach_speed < collapse_speed:
            return 1.0 - (1.0 - e0) * (approach_speed / collapse_speed) ** 0.75, e_s
        return e0, e_s
    if model == TC:
        if since_a < contact_duration or since_b < contact_duration:
            if min(since_a, since_b) < SAME_INSTANT * contact_duration:
                return 1.0, 1.0
            return 1.0, es0
    return e0, es0


@scalar
def collision_impulse(nx, ny, nz, vx, vy, vz, inv_mass, inv_rot, e_n, e_s):
    """The impulse J [N s] on grain a of a collision (module docstring) and the energy
    dissipated in its normal and tangential parts [J].

    n : unit normal from a to b;  v : v_ab, the relative velocity of the contact points
    [m/s] (Eq. 2);  inv_mass = 1/m_a + 1/m_b [1/kg];  inv_rot = R_a^2/I_a + R_b^2/I_b
    [1/kg];  e_n, e_s the restitutions.  Returns (Jx, Jy, Jz, dE_n, dE_s); J = 0 unless
    the contact points approach (v . n > 0: a moves towards b) and a mass is finite."""
    vn = vx * nx + vy * ny + vz * nz
    if vn <= 0.0 or inv_mass <= 0.0:
        return 0.0, 0.0, 0.0, 0.0, 0.0
    sx = vx - vn * nx
    sy = vy - vn * ny
    sz = vz - vn * nz
    mu_n = 1.0 / inv_mass
    mu_s = 1.0 / (inv_mass + inv_rot)
    a = -(1.0 + e_n) * mu_n * vn
    b = (e_s - 1.0) * mu_s
    dissipated_n = 0.5 * mu_n * vn * vn * (1.0 - e_n * e_n)
    dissipated_s = 0.5 * mu_s * (sx * sx + sy * sy + sz * sz) * (1.0 - e_s * e_s)
    return a * nx + b * sx, a * ny + b * sy, a * nz + b * sz, dissipated_n, dissipated_s


@scalar
def contact_velocity(nx, ny, nz, vax, vay, vaz, wax, way, waz, ra, vbx, vby, vbz,
                     wbx, wby, wbz, rb):
    """v_ab [m/s] of Pérez Eq. 2: v_a - v_b + (R_a w_a + R_b w_b) x n, n from a to b."""
    cx = ra * wax + rb * wbx
    cy = ra * way + rb * wby
    cz = ra * waz + rb * wbz
    return (vax - vbx + cy * nz - cz * ny,
            vay - vby + cz * nx - cx * nz,
            vaz - vbz + cx * ny - cy * nx)
