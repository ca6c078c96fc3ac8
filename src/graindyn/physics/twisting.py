"""Twisting resistance: torques [N m] on grain i about the normal n (grain j gets the
opposite couple) from w_n = (w_i - w_j).n [rad/s].  Each returns the magnitude M
(the torque is M n) and the energy [J] dissipated in the step dt [s].  In 2D
w_n = 0: disks do not twist.

'oquendo' (Oquendo Eq. 2): viscous, M = -4 pi gamma_nt m* R* xi w_n, from a kinetic
    friction spread over the contact area; gamma_nt [1/s].
'constant': M = -mu_tw a |f_n| sign(w_n), a = sqrt(R* xi) the contact radius (with
    Hertz pressure and sliding friction mu, full slip gives mu_tw = 3 pi mu/16,
    Lubkin 1951; a uniform pressure gives 2 mu/3).
'epsd': spring k_tw [N m/rad] and dashpot C_tw [N m s] on the twist angle, the
    spring capped at mu_tw a |f_n| and the dashpot off at the cap; history 1 value
    (the angle [rad]).
"""
from .._jit import scalar
from .indexing import hrow


@scalar
def twisting_oquendo_torque(gamma_nt, m_eff, r_eff, overlap, wn, dt):
    """M = -4 pi gamma_nt m* R* xi w_n [N m] (Oquendo Eq. 2) and its dissipation."""
    c = 4.0 * 3.141592653589793 * gamma_nt * m_eff * r_eff * overlap
    return -c * wn, c * wn * wn * dt


@scalar
def twisting_constant_torque(limit, wn, dt):
    """M = -limit sign(w_n) [N m], limit = mu_tw a |f_n|; zero when w_n = 0."""
    if wn == 0.0:
        return 0.0, 0.0
    m = -limit if wn > 0.0 else limit
    return m, limit * abs(wn) * dt


@scalar
def twisting_spring_torque(k_tw, c_tw, limit, wn, history, k, h, dt):
    """Elastic-plastic twisting spring-dashpot (the 1D form of the EPSD rolling law,
    Ai et al. 2011): theta (history[hrow(k, h)]) grows by w_n dt; the spring torque
    -k_tw theta is capped at |M| <= limit, theta then reset to match; the dashpot
    -c_tw w_n acts only below the cap.  Returns M [N m] and the energy dissipated
    [J], the work -M w_n dt not stored in the spring k_tw theta^2/2 (never < 0)."""
    theta = history[hrow(k, h)]
    before = 0.5 * k_tw * theta * theta
    theta += wn * dt
    m = -k_tw * theta
    if abs(m) > limit:
        m = limit if m > 0.0 else -limit
        theta = -m / k_tw
    else:
        m -= c_tw * wn
    history[hrow(k, h)] = theta
    return m, -m * wn * dt - (0.5 * k_tw * theta * theta - before)
