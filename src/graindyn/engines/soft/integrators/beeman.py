"""Beeman's algorithm for velocity-dependent forces (Perez Eq. 31-34), one coordinate
component at a time; a(t - dt) is history slot ``base``, v(t) slot ``base + 1``.

  r(t+h) = r + v h + (4 a - a(t-h)) h^2/6                      (Eq. 31)
  v_p    = v + (3 a - a(t-h)) h/2, seen by the force             (Eq. 32-33)
  v(t+h) = v + (5 a(t+h) + 8 a - a(t-h)) h/12                   (Eq. 34)
Start (no a(-h) yet): the first step is the velocity Verlet step of Perez Eq. 27-30,
whose local errors O(h^3) match Beeman's own, instead of a(-h) = a(0), which would
leave an O(h^2) velocity error in Eq. 34.
"""
from ...._jit import scalar


@scalar
def beeman_drift(h, started, vel, acc, history, base, i, d):
    """Coordinate increment (Eq. 31) and predicted velocity (Eq. 32) of component d."""
    v = vel[i, d]
    a = acc[i, d]
    history[base + 1, i, d] = v
    if started:
        previous = history[base, i, d]
        vel[i, d] = v + 0.5 * (3.0 * a - previous) * h
        return v * h + (4.0 * a - previous) * h * h / 6.0
    vel[i, d] = v + a * h
    return v * h + 0.5 * a * h * h


@scalar
def beeman_correct(h, started, a_new, vel, acc, history, base, i, d):
    """Velocity at t + h (Eq. 34) and the shift of the acceleration history."""
    a = acc[i, d]
    v = history[base + 1, i, d]
    if started:
        vel[i, d] = v + (5.0 * a_new + 8.0 * a - history[base, i, d]) * h / 12.0
    else:
        vel[i, d] = v + 0.5 * (a + a_new) * h
    history[base, i, d] = a
    acc[i, d] = a_new
    return 0.0
