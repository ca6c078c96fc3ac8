"""One contact's geometry and response, shared by the CPU's law loop (law_loop), the
per-contact rows of contacts.py and the GPU.

Geometry (Oquendo Eq. 3-4): n = (r_i - r_j)/|r_i - r_j|, overlap h = R_i + R_j - |r_i - r_j|,
the contact point sits at R'_i = R_i - h R_j/(R_i + R_j) from grain i, and the relative
velocity of i at that point is v_i - v_j - (R'_i w_i + R'_j w_j) x n.
"""
import math

from ..._jit import inlined, scalar
from ...physics.contact import contact_force


@inlined
def contact_response(model, params, a, b, overlap, lever_i, lever_j, r_eff, m_eff, nx, ny, nz,
                     dvx, dvy, dvz, wx, wy, wz, dwx, dwy, dwz, history, k, dt):
    """Force on i (3) [N] and the torques on i and j [N m]: the lever part (n x f_t)
    scaled by -R'_i and -R'_j plus the couple M of the rolling and twisting laws
    (+M on i, -M on j), and the energies dissipated [J].  w = R'_i w_i + R'_j w_j
    [m/s], dw = w_i - w_j [rad/s]; lever_j = 0 for a wall (R'_j = infinity)."""
    vx = dvx - (wy * nz - wz * ny)
    vy = dvy - (wz * nx - wx * nz)
    vz = dvz - (wx * ny - wy * nx)
    vn = vx * nx + vy * ny + vz * nz
    fn, ftx, fty, ftz, mx, my, mz, dn, dt_ = contact_force(
        model, params, a, b, overlap, r_eff, lever_i, lever_j, m_eff, nx, ny, nz, vn,
        vx - vn * nx, vy - vn * ny, vz - vn * nz, dwx, dwy, dwz, history, k, dt)
    cx = ny * ftz - nz * fty
    cy = nz * ftx - nx * ftz
    cz = nx * fty - ny * ftx
    return (fn * nx + ftx, fn * ny + fty, fn * nz + ftz,
            mx - lever_i * cx, my - lever_i * cy, mz - lever_i * cz,
            -mx - lever_j * cx, -my - lever_j * cy, -mz - lever_j * cz, dn, dt_)


@inlined
def planar_response(model, params, a, b, overlap, lever_i, lever_j, r_eff, m_eff, nx, ny,
                    dvx, dvy, w, dw, history, k, dt):
    """contact_response for two disks in the x-y plane (n and v in the plane, spins
    about z), without the components that are zero there: the force on i in the plane
    (2) [N], the torques about z on i and j [N m] and the energies dissipated [J], the
    numbers contact_response gives.  w = R'_i w_i + R'_j w_j [m/s], dw = w_i - w_j
    [rad/s] (their z components).  Written out because the compiler may not drop a
    product with a zero that IEEE arithmetic keeps (0 x inf, the sign of zero)."""
    vx = dvx + w * ny
    vy = dvy - w * nx
    vn = vx * nx + vy * ny
    fn, ftx, fty, _, _, _, mz, dn, dt_ = contact_force(
        model, params, a, b, overlap, r_eff, lever_i, lever_j, m_eff, nx, ny, 0.0, vn,
        vx - vn * nx, vy - vn * ny, 0.0, 0.0, 0.0, dw, history, k, dt)
    cz = nx * fty - ny * ftx
    return fn * nx + ftx, fn * ny + fty, mz - lever_i * cz, -mz - lever_j * cz, dn, dt_


@scalar
def contact_geometry(dx, dy, dz, r_i, r_j, m_i, m_j, fixed_i, fixed_j):
    """Touching pair with separation (dx, dy, dz) = r_i - r_j [m], radii [m], masses
    [kg] and fixed flags (non-zero: fixed): (overlap [m], overlap / smaller radius,
    lever_i, lever_j [m], R* [m], m* [kg], unit normal n (3) from j to i).  Branches
    the CPU's law loop evaluates in SIMD lanes (law_loop._law_rows)."""
    rsum = r_i + r_j
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    inv = 1.0 / dist
    overlap = rsum - dist
    if fixed_j != 0:
        m_eff = m_i
    elif fixed_i != 0:
        m_eff = m_j
    else:
        m_eff = m_i * m_j / (m_i + m_j)
    inv_sum = 1.0 / rsum
    share = overlap * inv_sum
    return (overlap, overlap / min(r_i, r_j), r_i - share * r_j, r_j - share * r_i,
            r_i * r_j * inv_sum, m_eff, dx * inv, dy * inv, dz * inv)
