"""Orientation updates: unit quaternions q = (w, x, y, z) mapping body to world frame.

Both updates are orthogonal maps of R^4, so |q| = 1 is kept to round-off without
renormalisation.  Each is applied as an increment, q + (M - I) q, with the small
coefficients of M - I computed directly: the rounding of a coefficient close to 1 (the
cosine, or (1 - s)/(1 + s)) would otherwise repeat identically at every step of a steady
rotation and drift |q| by about 1e-16 per step; in the increment form only the final
additions round at the scale of q, with signs that vary as q turns.
"""
import math

from .._jit import scalar


@scalar
def rotate_quaternion(q0, q1, q2, q3, px, py, pz):
    """exp(p/2) q: q turned by the exact rotation of angle |p| [rad] about the world-frame
    rotation vector p (the step's angular displacement, e.g. w dt).

    With u = |p|^2/4 the coefficients are cos(|p|/2) - 1 and sin(|p|/2)/|p|; below
    |p| = 0.2 rad (every practical step) they come from their Taylor series in u to
    u^5, whose truncation error is below 1e-18 relative: no square root and no
    trigonometric call per grain and step."""
    u = 0.25 * (px * px + py * py + pz * pz)
    if u == 0.0:
        return q0, q1, q2, q3
    if u < 0.01:
        # Horner forms of sum_k (-u)^k/(2k)! (k >= 1) and sum_k (-u)^k/(2k+1)!/2
        c = u * (-0.5 + u * (1.0 / 24.0 + u * (-1.0 / 720.0 + u * (1.0 / 40320.0 + u * (
            -1.0 / 3628800.0)))))
        s = 0.5 + u * (-1.0 / 12.0 + u * (1.0 / 240.0 + u * (-1.0 / 10080.0 + u * (
            1.0 / 725760.0 + u * (-1.0 / 79833600.0)))))
    else:
        angle = 2.0 * math.sqrt(u)
        sq = math.sin(0.25 * angle)
        c = -2.0 * sq * sq                   # cos(angle/2) - 1
        s = math.sin(0.5 * angle) / angle
    ax = s * px
    ay = s * py
    az = s * pz
    return (q0 + (c * q0 - ax * q1 - ay * q2 - az * q3),
            q1 + (c * q1 + ax * q0 + ay * q3 - az * q2),
            q2 + (c * q2 - ax * q3 + ay * q0 + az * q1),
            q3 + (c * q3 + ax * q2 - ay * q1 + az * q0))


@scalar
def quaternion_leapfrog(q0, q1, q2, q3, wx, wy, wz, dt):
    """Omelyan's quaternion leap-frog, Oquendo Eq. 18 with Q of Eq. 16:
    q(t+dt) = [(1 - dt^2 w^2/16) I + dt Q(w^b)] q(t) / (1 + dt^2 w^2/16),
    w^b the body-frame angular velocity at t + dt/2 [rad/s], obtained here from the
    world-frame w [rad/s] as w^b = q* w q.  The matrix is orthogonal (a Cayley
    transform), so |q| is kept; the rotation angle is 4 atan(|w| dt/4) instead of
    |w| dt, a local error O(dt^3)."""
    # w^b = R(q)^T w
    tx = 2.0 * (q2 * wz - q3 * wy)
    ty = 2.0 * (q3 * wx - q1 * wz)
    tz = 2.0 * (q1 * wy - q2 * wx)
    bx = wx - q0 * tx + (q2 * tz - q3 * ty)
    by = wy - q0 * ty + (q3 * tx - q1 * tz)
    bz = wz - q0 * tz + (q1 * ty - q2 * tx)
    s = dt * dt * (bx * bx + by * by + bz * bz) / 16.0
    inv = 1.0 / (1.0 + s)
    h = 0.5 * dt * inv
    c = -2.0 * s * inv                       # (1 - s)/(1 + s) - 1
    # Eq. 16: Q(w) q = 1/2 [[0,-bx,-by,-bz],[bx,0,bz,-by],[by,-bz,0,bx],[bz,by,-bx,0]] q
    return (q0 + (c * q0 + h * (-bx * q1 - by * q2 - bz * q3)),
            q1 + (c * q1 + h * (bx * q0 + bz * q2 - by * q3)),
            q2 + (c * q2 + h * (by * q0 - bz * q1 + bx * q3)),
            q3 + (c * q3 + h * (bz * q0 + by * q1 - bx * q2)))
