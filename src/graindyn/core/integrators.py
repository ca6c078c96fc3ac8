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

from .._jit import kernel, parallel, prange

NAMES = ("velocity_verlet",)
STAGES = np.array([1], dtype=np.int64)


def integrator_id(name):
    """Integer id of an integrator; ValueError naming the choices otherwise."""
    if name not in NAMES:
        raise ValueError(f"unknown integrator {name!r}; choose one of {list(NAMES)}")
    return NAMES.index(name)


@kernel
def rotate_quaternion(q, i, wx, wy, wz, dt):
    """q[i] <- exp(w dt/2) q[i]: the exact rotation by the angle |w| dt about w (world
    frame)."""
    w = math.sqrt(wx * wx + wy * wy + wz * wz)
    if w == 0.0:
        return
    half = 0.5 * w * dt
    c = math.cos(half)
    s = math.sin(half) / w
    ax = s * wx
    ay = s * wy
    az = s * wz
    q0, q1, q2, q3 = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    q[i, 0] = c * q0 - ax * q1 - ay * q2 - az * q3
    q[i, 1] = c * q1 + ax * q0 + ay * q3 - az * q2
    q[i, 2] = c * q2 - ax * q3 + ay * q0 + az * q1
    q[i, 3] = c * q3 + ax * q2 - ay * q1 + az * q0


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
        rotate_quaternion(orientations, i,
                          angular_velocities[i, 0] + 0.5 * angular_accelerations[i, 0] * dt,
                          angular_velocities[i, 1] + 0.5 * angular_accelerations[i, 1] * dt,
                          angular_velocities[i, 2] + 0.5 * angular_accelerations[i, 2] * dt, dt)
        for d in range(3):
            angular_velocities[i, d] += angular_accelerations[i, d] * dt


@parallel
def after_force(integrator, stage, dt, dim, forces, torques, masses, inertias, velocities,
                angular_velocities, accelerations, angular_accelerations, fixed):
    """Correct velocities with the new accelerations (Perez Eq. 30); dt = 0 only stores
    the accelerations (start-up)."""
    for i in prange(masses.size):
        if fixed[i]:
            continue
        for d in range(3):
            a = forces[i, d] / masses[i]
            alpha = torques[i, d] / inertias[i]
            if dim == 2:
                if d == 2:
                    a = 0.0
                else:
                    alpha = 0.0
            velocities[i, d] += 0.5 * (a - accelerations[i, d]) * dt
            angular_velocities[i, d] += 0.5 * (alpha - angular_accelerations[i, d]) * dt
            accelerations[i, d] = a
            angular_accelerations[i, d] = alpha
