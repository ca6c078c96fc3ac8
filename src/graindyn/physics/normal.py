"""Normal elastic laws, f = k xi with the secant stiffness k [N/m], and their stored
energy [J].  Linear spring: k = kn (Perez Eq. 14).  Hertz: k = 4/3 E* a with the
contact radius a = sqrt(R* xi) (Perez Eq. 17; Oquendo Eq. 1 with V_iV_j/(V_i+V_j) = E*).

overlap xi = R_i + R_j - |r_i - r_j| [m] (Perez Eq. 13), r_eff = R_i R_j/(R_i+R_j) [m].
"""
import math

from .._jit import scalar


@scalar
def normal_hooke_energy(overlap, kn):
    """Energy of the linear spring kn xi^2/2 [J]."""
    return 0.5 * kn * overlap * overlap


@scalar
def normal_hertz_energy(overlap, r_eff, youngs_eff):
    """Hertz energy 8/15 E* sqrt(R*) xi^(5/2) [J], the integral of the force."""
    return 8.0 / 15.0 * youngs_eff * math.sqrt(r_eff * overlap) * overlap * overlap


@scalar
def normal_hertz_stiffness(contact_radius, youngs_eff):
    """Secant stiffness f/xi = 4/3 E* a [N/m] of the Hertz law, a = sqrt(R* xi) [m]."""
    return 4.0 / 3.0 * youngs_eff * contact_radius
