"""Analytic and quasi-analytic truths for binary contact laws.

Reference values (collision time, restitution, Hertz peak values, time-step
estimates) that the DEM kernels are checked against.  Plain Python, numpy and
scipy; never called from numba kernels.  Equations follow
/work/shared/VALIDATION.md sections a1, a2 and b1.

Conventions: SI units; ``m_eff``, ``r_eff``, ``e_eff`` are the reduced mass,
radius and contact modulus of the pair (see ``effective_*``); ``v`` is the
relative normal impact speed.  "Clamped" means the normal force is limited to
be repulsive (F >= 0), so contact ends when the force, not the overlap,
reaches zero.
"""

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq
from scipy.special import gamma as _gamma_fn

__all__ = [
    "linear_collision_time",
    "linear_restitution",
    "linear_damping_ratio",
    "linear_textbook_restitution",
    "hertz_peak_overlap",
    "hertz_collision_time",
    "hertz_peak_force",
    "effective_modulus",
    "effective_radius",
    "effective_mass",
    "viscoelastic_restitution",
    "viscoelastic_delta",
    "viscoelastic_gamma_n",
    "tsuji_alpha",
    "tsuji_restitution",
    "rayleigh_time_step",
    "HERTZ_TC_CONSTANT",
    "VISCOELASTIC_C1",
    "VISCOELASTIC_C2",
]

# t_c = HERTZ_TC_CONSTANT * delta_max / v: 2 * int_0^1 dx / sqrt(1 - x^(5/2))
# = (4/5) B(2/5, 1/2) = 2 sqrt(pi) Gamma(7/5) / Gamma(9/10) = 2.943275...
HERTZ_TC_CONSTANT = 2.0 * math.sqrt(math.pi) * _gamma_fn(7.0 / 5.0) / _gamma_fn(9.0 / 10.0)

# Series eps = 1 - C1 delta + C2 delta^2 (Schwager & Poeschel 2008, PRE 78:051304).
VISCOELASTIC_C1 = (math.sqrt(math.pi) * _gamma_fn(3.0 / 5.0)
                   / (2.0 ** 0.2 * 5.0 ** 0.4 * _gamma_fn(21.0 / 10.0)))
VISCOELASTIC_C2 = 0.6 * VISCOELASTIC_C1 ** 2

# Polynomial alpha(e) of Tsuji et al. (1992) as used by LAMMPS `damping tsuji`.
_TSUJI_COEFFS = (1.2728, -4.2783, 11.087, -22.348, 27.467, -18.022, 4.8218)

_ODE_RTOL = 1e-12
_ODE_ATOL = 1e-14


def _positive(name, value, allow_inf=False):
    """Return float(value) after checking it is > 0 (and finite unless allowed)."""
    x = float(value)
    if not (x > 0.0) or (math.isinf(x) and not allow_inf) or math.isnan(x):
        allowed = "positive" + (" (inf allowed)" if allow_inf else " and finite")
        raise ValueError(f"{name} must be {allowed}, got {value!r}")
    return x


def _check_restitution(restitution):
    e = float(restitution)
    if not (0.0 < e <= 1.0):
        raise ValueError(f"restitution must lie in (0, 1], got {restitution!r}")
    return e


# --------------------------------------------------------------------------
# a1. Linear spring-dashpot
# --------------------------------------------------------------------------

def _linear_tc_scaled(d):
    """t_c * omega0 of the repulsive-only linear spring-dashpot for d = gamma/omega0."""
    if d < 1.0:
        # Underdamped; force zero at tan(w t) = -2 g w / (w^2 - g^2).  The atan2 form
        # pi - atan2(2gw, w^2-g^2) = atan2(2gw, g^2-w^2) covers both branches of
        # SP Eq. (gamma below/above omega0/sqrt 2) continuously and tends to 2/gamma
        # as w -> 0 without cancellation.
        w = math.sqrt((1.0 - d) * (1.0 + d))
        if w == 0.0:
            return 2.0 / d
        return math.atan2(2.0 * d * w, d * d - w * w) / w
    if d == 1.0:
        return 2.0  # critical damping: xi = v t exp(-g t), force zero at t = 2/g
    big_omega = math.sqrt((d - 1.0) * (d + 1.0))
    # ln[(g+W)/(g-W)]/W written as 2 artanh(W/g)/W (accurate near d = 1).
    return 2.0 * math.atanh(big_omega / d) / big_omega


def linear_collision_time(damping_ratio, omega0):
    """Collision time t_c [s] of the linear spring-dashpot with repulsive-only force.

    Equation of motion xi'' + 2 gamma xi' + omega0^2 xi = 0, xi(0) = 0, contact
    ends when F = m (2 gamma xi' + omega0^2 xi) reaches 0 (Schwager & Poeschel
    2007, Granular Matter 9:465; Perez Eq. 14-15).  With omega^2 = omega0^2 - gamma^2:
    gamma < omega0/sqrt2: t_c = [pi - arctan(2 gamma omega/(omega^2 - gamma^2))]/omega;
    omega0/sqrt2 < gamma < omega0: t_c = arctan(2 gamma omega/(gamma^2 - omega^2))/omega;
    gamma = omega0: t_c = 2/gamma;  gamma > omega0, W = sqrt(gamma^2 - omega0^2):
    t_c = ln[(gamma + W)/(gamma - W)]/W.

    damping_ratio = gamma/omega0 [-] (gamma = c/(2 m_eff)), omega0 = sqrt(k/m_eff) [rad/s].
    """
    d = float(damping_ratio)
    if not (d >= 0.0) or math.isinf(d):
        raise ValueError(f"damping_ratio must be finite and >= 0, got {damping_ratio!r}")
    w0 = _positive("omega0", omega0)
    return _linear_tc_scaled(d) / w0


def linear_restitution(damping_ratio):
    """Restitution eps = exp(-gamma t_c) [-] of the repulsive-only linear spring-dashpot.

    Depends only on damping_ratio = gamma/omega0 (Schwager & Poeschel 2007; Perez Eq. 16).
    """
    d = float(damping_ratio)
    if not (d >= 0.0) or math.isinf(d):
        raise ValueError(f"damping_ratio must be finite and >= 0, got {damping_ratio!r}")
    return math.exp(-d * _linear_tc_scaled(d))


def linear_damping_ratio(restitution):
    """Damping ratio gamma/omega0 [-] giving ``restitution`` with the repulsive-only law.

    Exact inverse of ``linear_restitution`` (Schwager & Poeschel 2007), solved with
    brentq on the monotone map; restitution must lie in (0, 1], 1 -> 0.
    """
    e = _check_restitution(restitution)
    if e == 1.0:
        return 0.0
    hi = 1.0
    while linear_restitution(hi) > e:
        hi *= 2.0
        if hi > 1e300:  # pragma: no cover - unreachable for e > 0
            raise ValueError(f"restitution {restitution!r} too small to invert")
    lo = 0.0 if hi == 1.0 else hi / 2.0
    return brentq(lambda d: linear_restitution(d) - e, lo, hi,
                  xtol=1e-300, rtol=4 * np.finfo(float).eps, maxiter=500)


def linear_textbook_restitution(damping_ratio):
    """Textbook restitution exp(-gamma pi/omega) [-], overlap-based end of contact.

    omega = omega0 sqrt(1 - (gamma/omega0)^2); attraction allowed, underdamped only
    (0 <= damping_ratio < 1).  For comparison with ``linear_restitution``.
    """
    d = float(damping_ratio)
    if not (0.0 <= d < 1.0):
        raise ValueError("textbook restitution needs 0 <= damping_ratio < 1, "
                         f"got {damping_ratio!r}")
    return math.exp(-d * math.pi / math.sqrt((1.0 - d) * (1.0 + d)))


# --------------------------------------------------------------------------
# b1. Elastic Hertz and effective parameters
# --------------------------------------------------------------------------

def effective_modulus(E1, nu1, E2, nu2):
    """Contact modulus E* [Pa]: 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2 (Johnson, Contact Mechanics).

    E2 = inf (rigid wall) is allowed; both rigid gives inf.  -1 < nu <= 0.5.
    """
    inv = 0.0
    for name, E, nu in (("E1", E1, nu1), ("E2", E2, nu2)):
        E = _positive(name, E, allow_inf=True)
        nu = float(nu)
        if not (-1.0 < nu <= 0.5):
            raise ValueError(f"Poisson ratio must lie in (-1, 0.5], got {nu!r}")
        if not math.isinf(E):
            inv += (1.0 - nu * nu) / E
    return math.inf if inv == 0.0 else 1.0 / inv


def _reduced(names, x1, x2, both_infinite):
    """1/(1/x1 + 1/x2) of two positive values, one of which may be infinite."""
    x1 = _positive(names[0], x1, allow_inf=True)
    x2 = _positive(names[1], x2, allow_inf=True)
    if math.isinf(x1) and math.isinf(x2):
        raise ValueError(both_infinite)
    return 1.0 / (1.0 / x1 + 1.0 / x2)


def effective_radius(r1, r2):
    """Effective radius R* [m]: 1/R* = 1/r1 + 1/r2; r2 = inf for a plane (R* = r1)."""
    return _reduced(("r1", "r2"), r1, r2,
                    "effective_radius: two planes have no finite contact radius")


def effective_mass(m1, m2):
    """Effective mass m* [kg]: 1/m* = 1/m1 + 1/m2; m2 = inf for a fixed wall (m* = m1)."""
    return _reduced(("m1", "m2"), m1, m2, "effective_mass: two infinite masses cannot collide")


def _hertz_args(m_eff, r_eff, e_eff, v):
    return (_positive("m_eff", m_eff), _positive("r_eff", r_eff),
            _positive("e_eff", e_eff), _positive("v", v))


def hertz_peak_overlap(m_eff, r_eff, e_eff, v):
    """Peak overlap [m] of the elastic Hertz law F = (4/3) E* sqrt(R*) delta^1.5.

    delta_max = (15 m* v^2 / (16 E* sqrt(R*)))^(2/5)  (Johnson, Contact Mechanics;
    energy balance m v^2/2 = (8/15) E* sqrt(R*) delta^(5/2)).  v [m/s] relative speed.
    """
    m, r, e, v = _hertz_args(m_eff, r_eff, e_eff, v)
    return (15.0 * m * v * v / (16.0 * e * math.sqrt(r))) ** 0.4


def hertz_collision_time(m_eff, r_eff, e_eff, v):
    """Duration [s] of an elastic Hertz impact: t_c = C delta_max / v.

    C = 2 sqrt(pi) Gamma(7/5)/Gamma(9/10) = 2.943275 (exact; equivalently
    t_c = 2.868266 (m*^2/(R* E*^2 v))^(1/5)); Johnson, Contact Mechanics.
    """
    m, r, e, v = _hertz_args(m_eff, r_eff, e_eff, v)
    return HERTZ_TC_CONSTANT * hertz_peak_overlap(m, r, e, v) / v


def hertz_peak_force(m_eff, r_eff, e_eff, v):
    """Peak force [N] of an elastic Hertz impact: F_max = (4/3) E* sqrt(R*) delta_max^1.5."""
    m, r, e, v = _hertz_args(m_eff, r_eff, e_eff, v)
    return 4.0 / 3.0 * e * math.sqrt(r) * hertz_peak_overlap(m, r, e, v) ** 1.5


# --------------------------------------------------------------------------
# a2. Viscoelastic Hertz
# --------------------------------------------------------------------------

def _bounce(rhs, end_event, t_max):
    """Integrate x'' = rhs(x, u) from x = 0, u = 1; return -u at the terminal event."""
    def fun(_t, y):
        return (y[1], rhs(max(y[0], 0.0), y[1]))

    end_event.terminal = True
    end_event.direction = -1
    sol = solve_ivp(fun, (0.0, t_max), (0.0, 1.0), method="DOP853",
                    rtol=_ODE_RTOL, atol=_ODE_ATOL, events=end_event)
    if sol.status != 1 or len(sol.y_events[0]) == 0:
        raise RuntimeError("contact did not end within the integration window "
                           f"(t_max = {t_max} dimensionless time units)")
    return float(-sol.y_events[0][0][1])


def viscoelastic_restitution(delta, clamped=True):
    """Restitution [-] of the viscoelastic Hertz law as a function of delta [-].

    F = rho (xi^1.5 + (3/2) A sqrt(xi) xi') (Brilliantov et al. 1996 PRE 53:5382;
    Perez Eq. 17).  With xi = X x, t = (X/v) tau and X^(5/2) = m v^2/rho the motion
    becomes x'' + delta sqrt(x) x' + x^1.5 = 0, x(0) = 0, x'(0) = 1, where
    delta = A kappa^(2/5) v^(1/5) and kappa = (3/2)^(5/2) rho/m (the (3/2) A/T
    factor equals delta exactly with this kappa).  Solved with solve_ivp (DOP853,
    rtol 1e-12).  clamped=True: contact ends when the force reaches zero
    (x + delta x' = 0, Schwager & Poeschel 2008 PRE 78:051304); clamped=False: when
    the overlap returns to zero (force turns attractive near the end).
    Small delta: eps = 1 - C1 delta + C2 delta^2, C1 = 1.153449, C2 = 0.6 C1^2.
    """
    d = float(delta)
    if not (d >= 0.0) or math.isinf(d):
        raise ValueError(f"delta must be finite and >= 0, got {delta!r}")
    if d == 0.0:
        return 1.0

    def rhs(x, u):
        return -x * math.sqrt(x) - d * math.sqrt(x) * u

    if clamped:
        def end(_t, y):  # F/(rho sqrt(x)) = x + delta x'
            return y[0] + d * y[1]
    else:
        def end(_t, y):
            return y[0]
    return _bounce(rhs, end, t_max=1e4)


def _viscoelastic_rho_kappa(m_eff, r_eff, e_eff):
    rho = 4.0 / 3.0 * e_eff * math.sqrt(r_eff)
    kappa = 1.5 ** 2.5 * rho / m_eff
    return rho, kappa


def viscoelastic_delta(gamma_n, m_eff, r_eff, e_eff, v):
    """Dimensionless damping delta [-] of the Oquendo-form viscoelastic Hertz law.

    F = (4/3) E* sqrt(R*) h^1.5 + m_eff gamma_n sqrt(h) h', gamma_n [1/(s m^0.5)],
    maps onto F = rho (h^1.5 + (3/2) A sqrt(h) h') with rho = (4/3) E* sqrt(R*),
    A = 2 m_eff gamma_n/(3 rho) [s]; delta = A kappa^(2/5) v^(1/5) with
    kappa = (3/2)^(5/2) rho/m_eff (= (3/2)^(3/2) Y sqrt(R)/(m (1-nu^2)) for
    identical spheres; Brilliantov et al. 1996; VALIDATION a2).
    """
    g = float(gamma_n)
    if not (g >= 0.0) or math.isinf(g):
        raise ValueError(f"gamma_n must be finite and >= 0, got {gamma_n!r}")
    m, r, e, v = _hertz_args(m_eff, r_eff, e_eff, v)
    rho, kappa = _viscoelastic_rho_kappa(m, r, e)
    a_visc = 2.0 * m * g / (3.0 * rho)
    return a_visc * kappa ** 0.4 * v ** 0.2


def _viscoelastic_delta_for(restitution, clamped):
    e = _check_restitution(restitution)
    if e == 1.0:
        return 0.0
    hi = 0.5
    while viscoelastic_restitution(hi, clamped) > e:
        hi *= 2.0
        if hi > 1e4:
            raise ValueError(f"restitution {restitution!r} is below what the viscoelastic "
                             "law reaches for delta <= 1e4")
    lo = 0.0 if hi == 0.5 else hi / 2.0
    return brentq(lambda d: viscoelastic_restitution(d, clamped) - e, lo, hi,
                  xtol=1e-14, rtol=1e-13)


def viscoelastic_gamma_n(restitution, m_eff, r_eff, e_eff, v_ref, clamped=True):
    """Damping gamma_n [1/(s m^0.5)] giving ``restitution`` at impact speed v_ref [m/s].

    Inverse of ``viscoelastic_restitution(viscoelastic_delta(...))``: brentq for delta,
    then gamma_n = 3 rho A/(2 m_eff), A = delta/(kappa^(2/5) v_ref^(1/5)).  The
    restitution of this law depends on speed (1 - eps ~ v^(1/5)); it is exact only at v_ref.
    """
    m, r, e, v = _hertz_args(m_eff, r_eff, e_eff, v_ref)
    d = _viscoelastic_delta_for(restitution, clamped)
    rho, kappa = _viscoelastic_rho_kappa(m, r, e)
    a_visc = d / (kappa ** 0.4 * v ** 0.2)
    return 3.0 * rho * a_visc / (2.0 * m)


# --------------------------------------------------------------------------
# Tsuji damping
# --------------------------------------------------------------------------

def tsuji_alpha(restitution):
    """Tsuji et al. (1992) polynomial alpha(e) [-] as used by LAMMPS ``damping tsuji``.

    alpha = 1.2728 - 4.2783 e + 11.087 e^2 - 22.348 e^3 + 27.467 e^4 - 18.022 e^5
    + 4.8218 e^6 (Marshall 2009 Eq. 53).  LAMMPS pair_granular docs: eta_n =
    alpha (m_eff k_n)^(1/2) with k_n = (4/3) E_eff a, a = sqrt(R delta), i.e. the
    *secant* Hertz stiffness F/delta, not the tangent 2 E a.  The current LAMMPS
    source (GRANULAR/gran_sub_mod_damping.cpp) multiplies alpha by sqrt(2) "for the
    effective mass convention (as in Tsuji 1992)" and uses sqrt(m_eff F_n/delta):
    Tsuji's alpha multiplies sqrt(m k) with the particle mass m = 2 m_eff.  Checked
    here: ``tsuji_restitution(sqrt(2) alpha(e), clamped=False)`` returns e within
    1.2e-3 for 0.1 <= e <= 0.99; without sqrt(2), or with clamping at low e, it
    does not.  Returns the raw polynomial (no sqrt(2)).
    """
    e = float(restitution)
    if not (0.0 <= e <= 1.0):
        raise ValueError(f"restitution must lie in [0, 1], got {restitution!r}")
    acc = 0.0
    for c in reversed(_TSUJI_COEFFS):
        acc = acc * e + c
    return acc


def tsuji_restitution(alpha, clamped=True):
    """Restitution [-] of F = k delta^1.5 + alpha sqrt(m_eff k_n(delta)) delta'.

    k_n(delta) = k sqrt(delta) is the secant Hertz stiffness (k = (4/3) E* sqrt(R*)),
    so the damping is alpha sqrt(m_eff k) delta^(1/4) delta' (Tsuji et al. 1992 form).
    Scaling delta by (m v^2/k)^(2/5) gives x'' + alpha x^(1/4) x' + x^1.5 = 0,
    independent of speed; solved with solve_ivp.  clamped=True ends contact when the
    force reaches zero (x^(5/4) + alpha x' = 0), else when the overlap does.  For
    LAMMPS ``damping tsuji`` pass alpha = sqrt(2) * tsuji_alpha(e).
    """
    a = float(alpha)
    if not (a >= 0.0) or math.isinf(a):
        raise ValueError(f"alpha must be finite and >= 0, got {alpha!r}")
    if a == 0.0:
        return 1.0

    def rhs(x, u):
        return -x * math.sqrt(x) - a * math.sqrt(math.sqrt(x)) * u

    if clamped:
        def end(_t, y):
            return max(y[0], 0.0) ** 1.25 + a * y[1]
    else:
        def end(_t, y):
            return y[0]
    return _bounce(rhs, end, t_max=1e4)


# --------------------------------------------------------------------------
# Time step
# --------------------------------------------------------------------------

def rayleigh_time_step(radius, density, shear_modulus, poisson):
    """Rayleigh time step T_R [s] = pi R sqrt(rho/G) / (0.1631 nu + 0.8766).

    radius [m], density [kg/m^3], shear modulus G [Pa], Poisson ratio nu [-]
    (VALIDATION b1; Karrech diorite R = 3.2 mm gives 4.17 us).
    """
    r = _positive("radius", radius)
    rho = _positive("density", density)
    g = _positive("shear_modulus", shear_modulus)
    nu = float(poisson)
    if not (-1.0 < nu <= 0.5):
        raise ValueError(f"Poisson ratio must lie in (-1, 0.5], got {poisson!r}")
    return math.pi * r * math.sqrt(rho / g) / (0.1631 * nu + 0.8766)
