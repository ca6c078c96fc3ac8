"""Integrators, each as stages around force evaluations, chosen by an integer id.

A step of integrator ``k`` is: for each stage s < STAGES[k]: ``before_force(k, s)``,
forces, ``after_force(k, s)``.  Only free grains move (fixed[i] == 1 stays put).

velocity_verlet (Perez Eq. 27-30), velocity Verlet with a velocity predictor so that
velocity-dependent (damping) forces see v(t + dt) to O(dt^2):
  r(t+dt) = r + v dt + a dt^2/2;   v_p = v + a dt;   a(t+dt) = F(r(t+dt), v_p)/m;
  v(t+dt) = v_p + (a(t+dt) - a(t)) dt/2.
The same for rotation with w and alpha = torque/I (spheres and disks have isotropic
inertia), and the orientation q turned by the exact rotation of angle |w_mid| dt about
w_mid = w + alpha dt/2, which keeps |q| = 1 to round-off.
"""
import math

import numpy as np

from .._jit import parallel, prange, scalar
from .contacts import gather_grain
from .neighbors import min_image

NAMES = ("velocity_verlet",)
STAGES = np.array([1], dtype=np.int64)


def integrator_id(name):
    """Integer id of an integrator; ValueError naming the choices otherwise."""
    if name not in NAMES:
        raise ValueError(f"unknown integrator {name!r}; choose one of {list(NAMES)}")
    return NAMES.index(name)


@scalar
def rotate_quaternion(q0, q1, q2, q3, wx, wy, wz, dt):
    """exp(w dt/2) q: the exact rotation of q by the angle |w| dt about w (world frame)."""
    w = math.sqrt(wx * wx + wy * wy + wz * wz)
    if w == 0.0:
        return q0, q1, q2, q3
    half = 0.5 * w * dt
    c = math.cos(half)
    s = math.sin(half) / w
    ax = s * wx
    ay = s * wy
    az = s * wz
    return (c * q0 - ax * q1 - ay * q2 - az * q3, c * q1 + ax * q0 + ay * q3 - az * q2,
            c * q2 - ax * q3 + ay * q0 + az * q1, c * q3 + ax * q2 - ay * q1 + az * q0)


@parallel
def before_force(integrator, stage, dt, positions, velocities, angular_velocities,
                 orientations, accelerations, angular_accelerations, fixed):
    """Drift and predict (Perez Eq. 27-28) before the force evaluation of ``stage``."""
    for i in prange(positions.shape[0]):
        if fixed[i]:
            continue
        for d in range(3):
            positions[i, d] += velocities[i, d] * dt + 0.5 * accelerations[i, d] * dt * dt
            velocities[i, d] += accelerations[i, d] * dt
        q = rotate_quaternion(
            orientations[i, 0], orientations[i, 1], orientations[i, 2], orientations[i, 3],
            angular_velocities[i, 0] + 0.5 * angular_accelerations[i, 0] * dt,
            angular_velocities[i, 1] + 0.5 * angular_accelerations[i, 1] * dt,
            angular_velocities[i, 2] + 0.5 * angular_accelerations[i, 2] * dt, dt)
        for c in range(4):
            orientations[i, c] = q[c]
        for d in range(3):
            angular_velocities[i, d] += angular_accelerations[i, d] * dt


@parallel
def after_force(integrator, stage, dt, dim, gravity, pairs, wall_start, wall_force,
                wall_torque, forces, torques, masses, inertias, positions, reference_positions,
                velocities, angular_velocities, accelerations, angular_accelerations, fixed,
                periodic_flag, periodic_length, block_scratch):
    """Gather contact forces onto grains, correct velocities with the new accelerations
    (Perez Eq. 30; dt = 0 only stores the accelerations at start-up), and return the
    largest displacement since the last neighbour build plus a bound on the next drift,
    |r - r_ref| + |v| dt + |a| dt^2/2 [m], for the half-skin rule.  One pass over grains,
    in fixed blocks, so the result does not depend on thread timing."""
    (start, partners, history, scratch_start, scratch_partners, scratch_history,
     reverse_start, reverse_pairs, pair_force, pair_torque_i, pair_torque_j) = pairs
    n = masses.size
    nblock = block_scratch.size
    for b in prange(nblock):
        best = 0.0
        for i in range(b * n // nblock, (b + 1) * n // nblock):
            f = gather_grain(i, masses[i], gravity, start, reverse_start, reverse_pairs,
                             pair_force, pair_torque_i, pair_torque_j, wall_start, wall_force,
                             wall_torque)
            d2 = 0.0
            v2 = 0.0
            a2 = 0.0
            inverse_mass = 1.0 / masses[i]
            inverse_inertia = 1.0 / inertias[i]
            for d in range(3):
                forces[i, d] = f[d]
                torques[i, d] = f[3 + d]
                if not fixed[i]:
                    a = f[d] * inverse_mass
                    alpha = f[3 + d] * inverse_inertia
                    if dim == 2:
                        if d == 2:
                            a = 0.0
                        else:
                            alpha = 0.0
                    velocities[i, d] += 0.5 * (a - accelerations[i, d]) * dt
                    angular_velocities[i, d] += 0.5 * (alpha - angular_accelerations[i, d]) * dt
                    accelerations[i, d] = a
                    angular_accelerations[i, d] = alpha
                dx = min_image(positions[i, d] - reference_positions[i, d], periodic_flag[d],
                               periodic_length[d])
                d2 += dx * dx
                v2 += velocities[i, d] * velocities[i, d]
                a2 += accelerations[i, d] * accelerations[i, d]
            best = max(best, math.sqrt(d2) + math.sqrt(v2) * dt + 0.5 * math.sqrt(a2) * dt * dt)
        block_scratch[b] = best
    return block_scratch.max()
