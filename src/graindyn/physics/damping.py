"""Normal damping laws: the dashpot coefficient c [kg/s] so that f_d = c dxi/dt.

The total normal force is clamped repulsive, f_n = max(0, f_el + c dxi/dt)
(Perez Eq. 14 and 17), in physics/contact.py.
"""
import math

from .._jit import scalar


@scalar
def damping_linear_coefficient(m_eff, kn, damping_ratio, damping_constant):
    """Gamma = 2 beta sqrt(kn m*) + Gamma_0 [kg/s] (Perez Eq. 14-16, beta = gamma/Omega).

    beta comes from the restitution through the repulsive-only relation of
    Schwager & Poeschel 2007 (physics.reference.linear_damping_ratio).
    """
    return 2.0 * damping_ratio * math.sqrt(kn * m_eff) + damping_constant


@scalar
def damping_viscoelastic_coefficient(m_eff, overlap, gamma_n):
    """c = m* gamma_n sqrt(xi) [kg/s] (Oquendo Eq. 1; Perez Eq. 17 with Gamma_H = m* gamma_n)."""
    return m_eff * gamma_n * math.sqrt(overlap)


@scalar
def damping_tsuji_coefficient(m_eff, stiffness, alpha):
    """c = sqrt(2) alpha sqrt(m* k) [kg/s], k = f_el/xi the secant stiffness [N/m]:
    Tsuji et al. 1992, as LAMMPS `damping tsuji`.

    For Hertz k = 4/3 E* sqrt(R* xi), so c grows as
    xi^(1/4) and the restitution does not depend on the impact speed; alpha(e) from
    physics.reference.tsuji_alpha.  The sqrt(2) is Tsuji's effective-mass convention,
    as in the LAMMPS source; with it the polynomial reproduces e within 1.1e-3 for
    0.1 <= e <= 0.99 when the force may turn attractive (``limit_damping`` off).
    """
    return 1.4142135623730951 * alpha * math.sqrt(m_eff * stiffness)


@scalar
def damping_karrech_coefficient(m_eff, tangent_stiffness, alpha):
    """c = 2 alpha sqrt(m* k) [kg/s] (Karrech Eq. 7, gamma_{n,t} = 2 alpha sqrt(m k)).

    Karrech writes the force as (m/2) gamma v with gamma = 2 alpha sqrt(m k); the units
    only agree when (m/2) is read as the reduced mass of the pair, which multiplies
    nothing: c = 2 alpha sqrt(m* k).  k is the tangent stiffness: df/dxi = 2 E* a for
    Hertz (so c grows as xi^(1/4) and the restitution does not depend on the speed),
    kn for a linear spring, 8 G* a for Mindlin's tangential spring.  For a linear
    spring alpha = -ln e/sqrt(pi^2 + ln^2 e) (Da Cruz et al. 2005) gives restitution e
    when the force may pull.
    """
    return 2.0 * alpha * math.sqrt(m_eff * tangent_stiffness)
