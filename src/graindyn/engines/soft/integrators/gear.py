"""Gear predictor-corrector for r'' = F/m, one coordinate component at a time.

The derivatives are kept unscaled: v, a in the State, and a' (jerk), a'' (snap),
a''' (crackle) in history slots base, base + 1, base + 2 (as many as the scheme has),
so the history means the same thing whatever dt.  With h = dt:
  predictor (Perez Eq. 36, Karrech Eq. 2): the Taylor series of each derivative;
  e = F(r_p, v_p)/m - a_p (Karrech Eq. 3; Perez Eq. 37: Delta A = e h^2/2);
  corrector (Perez Eq. 38, Karrech Eq. 4):
    r += K0 e h^2, v += K1 e h, a += K2 e, a' += K3 e/h, a'' += K4 e/h^2, a''' += K5 e/h^3.
K for each scheme, from the papers' coefficients:
  gear3 (Karrech Eq. 4, c = (0, 1, 1) applied as c0 h^2/2, c1 h, c2 to Delta a, as
    printed): K = (0, 1, 1).  Note: v(t+h) = v + a(t+h) h, first order.
  gear5 (Gear's 5-value corrector for second-order equations, c = (19/120, 3/4, 1,
    1/2, 1/12) on the scaled derivatives h^k r^(k)/k!): K = (19/240, 3/8, 1, 3/2, 1, 0).
  gear6 (Perez Eq. 38, (3/16, 251/360, 2, 11/3, 4, 2) on V = v h, A = a h^2,
    J = a' h^3, ...): K = (3/32, 251/720, 1, 11/6, 2, 1).
Start: r, v, a are known at t0 but a', a'', a''' are not; zeros would leave an
O(h^2) velocity error (the damped case has a'(t0) != 0) and cap the order at 2.
Simulation._start_derivatives estimates them by integrating a few steps forward and
back to t0 (negative h: the formulas hold for either sign) and keeping only the
derivatives the corrector has built up, then restoring everything else.
"""
import numpy as np

from ...._jit import scalar
from .ids import GEAR3, GEAR5, GEAR6

GEAR_K = np.zeros((GEAR6 + 1, 6))
GEAR_K[GEAR3] = (0.0, 1.0, 1.0, 0.0, 0.0, 0.0)
GEAR_K[GEAR5] = (19.0 / 240.0, 3.0 / 8.0, 1.0, 1.5, 1.0, 0.0)
GEAR_K[GEAR6] = (3.0 / 32.0, 251.0 / 720.0, 1.0, 11.0 / 6.0, 2.0, 1.0)


@scalar
def gear_drift(derivatives, h, vel, acc, history, base, i, d):
    """Predictor of component d: returns r_p - r, leaves v_p, a_p in vel, acc and the
    predicted higher derivatives in the history."""
    jerk = history[base, i, d] if derivatives > 0 else 0.0
    snap = history[base + 1, i, d] if derivatives > 1 else 0.0
    crackle = history[base + 2, i, d] if derivatives > 2 else 0.0
    v = vel[i, d]
    a = acc[i, d]
    if derivatives > 0:
        history[base, i, d] = jerk + h * (snap + h * crackle / 2.0)
    if derivatives > 1:
        history[base + 1, i, d] = snap + h * crackle
    vel[i, d] = v + h * (a + h * (jerk / 2.0 + h * (snap / 6.0 + h * crackle / 24.0)))
    acc[i, d] = a + h * (jerk + h * (snap / 2.0 + h * crackle / 6.0))
    return h * (v + h * (a / 2.0 + h * (jerk / 6.0 + h * (snap / 24.0 + h * crackle / 120.0))))


@scalar
def gear_correct(integrator, derivatives, h, a_new, vel, acc, history, base, i, d):
    """Corrector of component d; returns the position correction K0 e h^2."""
    k = GEAR_K[integrator]
    e = a_new - acc[i, d]
    vel[i, d] += k[1] * e * h
    acc[i, d] += k[2] * e
    if derivatives > 0:
        history[base, i, d] += k[3] * e / h
    if derivatives > 1:
        history[base + 1, i, d] += k[4] * e / (h * h)
    if derivatives > 2:
        history[base + 2, i, d] += k[5] * e / (h * h * h)
    return k[0] * e * h * h
