"""Tangential (friction) laws.  Forces [N] act on grain i; v_t [m/s] is the tangential
velocity of i relative to j at the contact point; each returns the force and the
energy [J] dissipated during the step dt [s].
"""
import math

from .._jit import scalar


@scalar
def tangential_coulomb_force(mu, fn, vtx, vty, vtz, dt):
    """Pure sliding friction f_t = -mu f_n v_t/|v_t| (Perez Eq. 19); zero when v_t = 0."""
    speed = math.sqrt(vtx * vtx + vty * vty + vtz * vtz)
    if speed == 0.0:
        return 0.0, 0.0, 0.0, 0.0
    s = -mu * fn / speed
    return s * vtx, s * vty, s * vtz, mu * fn * speed * dt


@scalar
def tangential_spring_force(kt, eta_t, mu, fn, nx, ny, nz, vtx, vty, vtz, history, k, dt):
    """Capped tangential spring with dashpot: Cundall-Strack (Perez Eq. 20-23) in 3D.

    history[k, 0:3] holds the spring elongation zeta [m].  Each step zeta is first rotated
    into the current tangent plane keeping its length, then grows by v_t dt (Eq. 20);
    the trial force f = -kt zeta - eta_t v_t is capped at mu f_n (Eq. 22), and when it
    is capped zeta is reset so that the spring and dashpot give exactly the capped
    force: the elongation stops growing while the contact slides (Eq. 23).
    kt [N/m], eta_t [kg/s].  Returns f_t (3) and the energy dissipated in the step,
    the work -f_t.v_t dt not stored in the spring.
    """
    zx = history[k, 0]
    zy = history[k, 1]
    zz = history[k, 2]
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
    fx = -kt * zx - eta_t * vtx
    fy = -kt * zy - eta_t * vty
    fz = -kt * zz - eta_t * vtz
    f2 = fx * fx + fy * fy + fz * fz
    cap = mu * fn
    if f2 > cap * cap:
        s = cap / math.sqrt(f2)
        fx *= s
        fy *= s
        fz *= s
        if kt > 0.0:
            zx = -(fx + eta_t * vtx) / kt
            zy = -(fy + eta_t * vty) / kt
            zz = -(fz + eta_t * vtz) / kt
        else:
            zx = 0.0
            zy = 0.0
            zz = 0.0
    history[k, 0] = zx
    history[k, 1] = zy
    history[k, 2] = zz
    energy_after = 0.5 * kt * (zx * zx + zy * zy + zz * zz)
    work = -(fx * vtx + fy * vty + fz * vtz) * dt
    return fx, fy, fz, work - (energy_after - energy_before)


@scalar
def tangential_mindlin_stiffness(shear_eff, contact_radius):
    """Mindlin no-slip stiffness kt = 8 G* a [N/m], a = sqrt(R* xi) (Karrech Eq. 6)."""
    return 8.0 * shear_eff * contact_radius


@scalar
def tangential_spring_energy(kt, history, k):
    """Energy kt |zeta|^2/2 [J] stored in the tangential spring history[k, 0:3]."""
    return 0.5 * kt * (history[k, 0] ** 2 + history[k, 1] ** 2 + history[k, 2] ** 2)
