"""The Verlet family, one coordinate component at a time (translation, or the rotation
vector for rotation: the same formulas with w, alpha = torque/I for v, a).

``*_drift`` runs before the force evaluation of a stage: it returns the coordinate
increment [m] (or [rad]) and leaves in ``vel`` the velocity the force sees.
``*_correct`` runs after it with the new acceleration ``a_new``: it stores the velocity
at the end of the stage and returns a coordinate increment to apply after the force
(non-zero only for the last drift of the optimized velocity Verlet).  With dt = h:

velocity_verlet (Perez Eq. 27-30): r += v h + a h^2/2; force sees v_p = v + a h;
    v = v_p + (a_new - a) h/2.
velocity_verlet_plain (Perez Eq. 24-26, with the a h^2/2 of Eq. 27; the a h^2 printed
    in Eq. 24 is a misprint): v += a h/2; r += v h; force sees that half-step v;
    v += a_new h/2.
verlet (position form): r(t+h) = r + D, D = r(t) - r(t-h) + a h^2 kept in the history
    (the sum form: the same numbers as 2 r(t) - r(t-h) + a h^2 with less round-off);
    force sees D/h; reported v = D/h + a_new h/2 (second order).  Exact start: the
    first D = v h + a h^2/2.
leap_frog: u(t+h/2) = u(t-h/2) + a h; r += u h; force sees u; reported
    v = u + a_new h/2.  Exact start: u(h/2) = v(0) + a(0) h/2.
optimized_velocity_verlet (Oquendo Eq. 11-15): stage 0 drifts xi v h, kick a_new h/2;
    stage 1 drifts (1 - 2 xi) v h, kick a_new h/2, drift xi v h after the force.
In exact arithmetic verlet, leap_frog and velocity_verlet_plain give the same
trajectory (Stormer-Verlet); they differ in round-off, in the variable carried from
step to step, and in nothing else.
"""
from ...._jit import scalar
from .ids import LEAP_FROG, OPTIMIZED_VELOCITY_VERLET, VELOCITY_VERLET, VELOCITY_VERLET_PLAIN, \
    VERLET

# Oquendo Eq. 11-15, 1/2 - c/12 + 1/(6c), c = (2 sqrt(326) + 36)^(1/3) (VALIDATION g)
XI = 0.1931833275037836


@scalar
def verlet_drift(integrator, stage, h, started, vel, acc, history, base, i, d):
    """Coordinate increment of component d of grain i before the force of ``stage``."""
    v = vel[i, d]
    a = acc[i, d]
    if integrator == VELOCITY_VERLET:
        vel[i, d] = v + a * h
        return v * h + 0.5 * a * h * h
    if integrator == VELOCITY_VERLET_PLAIN:
        u = v + 0.5 * a * h
        vel[i, d] = u
        return u * h
    if integrator == VERLET:
        if started:
            step = history[base, i, d] + a * h * h
        else:
            step = v * h + 0.5 * a * h * h
        history[base, i, d] = step
        vel[i, d] = step / h
        return step
    if integrator == LEAP_FROG:
        if started:
            u = history[base, i, d] + a * h
        else:
            u = v + 0.5 * a * h
        history[base, i, d] = u
        vel[i, d] = u
        return u * h
    # OPTIMIZED_VELOCITY_VERLET
    if stage == 0:
        return XI * h * v
    return (1.0 - 2.0 * XI) * h * v


@scalar
def verlet_correct(integrator, stage, h, a_new, vel, acc, history, base, i, d):
    """Velocity of component d at the end of ``stage`` from the new acceleration; returns
    the increment to apply after the force."""
    a = acc[i, d]
    acc[i, d] = a_new
    if integrator == VELOCITY_VERLET:
        vel[i, d] += 0.5 * (a_new - a) * h
    elif integrator == VELOCITY_VERLET_PLAIN:
        vel[i, d] += 0.5 * a_new * h
    elif integrator == VERLET:
        vel[i, d] = history[base, i, d] / h + 0.5 * a_new * h
    elif integrator == LEAP_FROG:
        vel[i, d] = history[base, i, d] + 0.5 * a_new * h
    elif integrator == OPTIMIZED_VELOCITY_VERLET:
        v = vel[i, d] + 0.5 * a_new * h
        vel[i, d] = v
        if stage == 1:
            return XI * h * v
    return 0.0
