"""Normal elastic laws, f = k xi with the secant stiffness k [N/m], and their stored
energy [J].  Linear spring: k = kn (Perez Eq. 14).  Hertz: k = 4/3 E* a with the
contact radius a = sqrt(R* xi) (Perez Eq. 17; Oquendo Eq. 1 with V_iV_j/(V_i+V_j) = E*).
Walton-Braun: two linear springs, one for loading and one for unloading, in the two
variants of Perez Fig. 2 (history: one value per contact).  All these laws are the
same for disks (2D) and spheres: Hertz is the 3D law, the linear ones are used for
both.

overlap xi = R_i + R_j - |r_i - r_j| [m] (Perez Eq. 13), r_eff = R_i R_j/(R_i+R_j) [m].
"""
import math

from .._jit import scalar
from .indexing import hrow


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


@scalar
def normal_walton_braun_force(overlap, kn, restitution, history, k, h):
    """Walton & Braun (1986) loading/unloading springs, plastic form (Perez Sec. 3.1,
    Fig. 2a): f = min(k1 xi, k2 (xi - xi0)), f >= 0, with k1 = kn on loading and the
    stiffer k2 = kn/e^2 on unloading; xi0 = xi_max (1 - e^2) is where the force
    vanishes, xi_max the largest overlap of the contact (history[hrow(k, h)]).

    Energy returned / energy loaded = k1/k2 = e^2, so the restitution is the input e
    whatever the speed.  Reloading after a partial unloading follows the k2 line up to
    xi_max, then k1.  Returns (f [N], energy dissipated in the step [J]): the loss is a
    function of the state, k1 (1 - e^2) (xi_max_new^2 - xi_max_old^2)/2, so with
    ``normal_walton_braun_energy`` the bookkeeping is exact.
    """
    e2 = restitution * restitution
    old = history[hrow(k, h)]
    # max(old, overlap), min(loading, unloading) and max(f, 0) written as the selects
    # they are: numba's min and max kept the CPU's law loop out of SIMD lanes
    peak = overlap if overlap > old else old
    history[hrow(k, h)] = peak
    loading = kn * overlap
    unloading = kn / e2 * (overlap - peak * (1.0 - e2))
    f = unloading if unloading < loading else loading
    return 0.0 if f < 0.0 else f, 0.5 * kn * (1.0 - e2) * (peak * peak - old * old)


@scalar
def normal_walton_braun_energy(overlap, kn, restitution, history, k, h):
    """Energy [J] the plastic Walton-Braun spring gives back on unloading from the
    present state: k2 (xi - xi0)^2/2 with k2 = kn/e^2, xi0 = xi_max (1 - e^2)."""
    e2 = restitution * restitution
    x = overlap - history[hrow(k, h)] * (1.0 - e2)
    return 0.5 * kn / e2 * x * x if x > 0.0 else 0.0


@scalar
def normal_walton_braun_silo_force(overlap, kn, restitution, history, k, h):
    """Walton-Braun springs as in the silo model (Perez Sec. 3.1 Fig. 2b, Sec. 4):
    f = kn xi while the overlap grows, f = e^2 kn xi while it shrinks (the
    paper's "reduced by a restitution factor eps^2", eps^2 = 0.9 there), so the
    restitution is e.  Loading and unloading are told apart by comparing the overlap
    with its value at the previous evaluation (history[hrow(k, h)]).

    Returns (f [N], energy dissipated in the step [J]): the stored energy is taken as
    what unloading would give back, e^2 kn xi^2/2, so loading by d(xi^2/2) costs
    (1 - e^2) kn d(xi^2/2) and unloading costs nothing.
    """
    e2 = restitution * restitution
    old = history[hrow(k, h)]
    history[hrow(k, h)] = overlap
    if overlap >= old:
        return kn * overlap, 0.5 * (1.0 - e2) * kn * (overlap * overlap - old * old)
    return e2 * kn * overlap, 0.0
