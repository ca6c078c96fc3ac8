"""One contact, all modes: the integer-id dispatcher over the registered sub-models.

Order (as LAMMPS GRANULAR): elastic normal force, damping, clamp to repulsive,
tangential law capped by the normal force.  Rolling and twisting resistance have the
id 0 ("none") only, for now.  Law ids and table columns come from physics/registry.py.
"""
import math

from .._jit import scalar
from .damping import (damping_linear_coefficient, damping_tsuji_coefficient,
                      damping_viscoelastic_coefficient)
from .normal import normal_hertz_energy, normal_hertz_stiffness, normal_hooke_energy
from .registry import COL, DAMPING, NORMAL, TANGENTIAL
from .tangential import (tangential_coulomb_force, tangential_mindlin_stiffness,
                         tangential_spring_energy, tangential_spring_force)

_HOOKE = NORMAL["hooke"]
_LINEAR = DAMPING["linear"]
_VISCOELASTIC = DAMPING["viscoelastic"]
_TSUJI = DAMPING["tsuji"]
_COULOMB = TANGENTIAL["coulomb"]
_CUNDALL = TANGENTIAL["cundall_strack"]
_MINDLIN = TANGENTIAL["mindlin"]
_KN = COL["kn"]
_E = COL["youngs_eff"]
_G = COL["shear_eff"]
_BETA = COL["damping_ratio"]
_GAMMA0 = COL["damping_constant"]
_GAMMA_N = COL["gamma_n"]
_ALPHA = COL["tsuji_alpha"]
_KT = COL["kt"]
_XT = COL["tangential_damping"]
_MU = COL["friction_sliding"]


@scalar
def contact_force(model, params, a, b, overlap, r_eff, m_eff, nx, ny, nz, vn, vtx, vty, vtz,
                  history, k, dt):
    """Force on grain i of one contact with overlap > 0.

    model : (6,) int ids (normal, damping, tangential, rolling, twisting) and the
        limit_damping flag: 1 keeps the normal force repulsive (Perez Eq. 14, 17),
        0 lets the dashpot pull at the end of a contact (the LAMMPS default)
    params[a, b] : (NCOL,) parameters of the material pair (a, b);  overlap [m];
    r_eff [m];  m_eff [kg]
    n : unit normal from j to i;  vn = v_rel.n [m/s] (negative when approaching)
    v_t : tangential relative velocity of i at the contact point [m/s]
    history[k] : this contact's history values, updated in place;  dt [s]
    (Whole arrays and indices are passed rather than row views: a view costs two
    atomic reference-count updates per contact in numba.)
    Returns (f_n >= 0 [N], f_t (3) [N], normal and tangential energy dissipated [J]).
    """
    radius = math.sqrt(r_eff * overlap)  # Hertz contact radius a [m]
    if model[0] == _HOOKE:
        stiffness = params[a, b, _KN]
    else:
        stiffness = normal_hertz_stiffness(radius, params[a, b, _E])
    f_el = stiffness * overlap  # Perez Eq. 14 / Eq. 17, Oquendo Eq. 1
    damping = model[1]
    if damping == _LINEAR:
        c = damping_linear_coefficient(m_eff, params[a, b, _KN], params[a, b, _BETA],
                                       params[a, b, _GAMMA0])
    elif damping == _VISCOELASTIC:
        c = damping_viscoelastic_coefficient(m_eff, overlap, params[a, b, _GAMMA_N])
    elif damping == _TSUJI:
        c = damping_tsuji_coefficient(m_eff, stiffness, params[a, b, _ALPHA])
    else:
        c = 0.0
    rate = -vn
    fn = f_el + c * rate
    if fn < 0.0 and model[5] != 0:
        fn = 0.0
    dissipated_n = (fn - f_el) * rate * dt
    cap = abs(fn)  # the friction limit uses |f_n| when the dashpot pulls (as LAMMPS)
    tangential = model[2]
    if tangential == _COULOMB:
        ftx, fty, ftz, dissipated_t = tangential_coulomb_force(params[a, b, _MU], cap, vtx, vty,
                                                               vtz, dt)
    elif tangential == _CUNDALL:
        ftx, fty, ftz, dissipated_t = tangential_spring_force(
            params[a, b, _KT], params[a, b, _XT] * c, params[a, b, _MU], cap, nx, ny, nz,
            vtx, vty, vtz, history, k, dt)
    elif tangential == _MINDLIN:
        kt = tangential_mindlin_stiffness(params[a, b, _G], radius)
        ftx, fty, ftz, dissipated_t = tangential_spring_force(
            kt, params[a, b, _XT] * c, params[a, b, _MU], cap, nx, ny, nz, vtx, vty, vtz,
            history, k, dt)
    else:
        ftx = 0.0
        fty = 0.0
        ftz = 0.0
        dissipated_t = 0.0
    return fn, ftx, fty, ftz, dissipated_n, dissipated_t


@scalar
def contact_energy(model, params, a, b, overlap, r_eff, history, k):
    """Elastic energy [J] stored in one contact: normal spring plus tangential spring."""
    if overlap <= 0.0:
        return 0.0
    if model[0] == _HOOKE:
        energy = normal_hooke_energy(overlap, params[a, b, _KN])
    else:
        energy = normal_hertz_energy(overlap, r_eff, params[a, b, _E])
    if model[2] == _CUNDALL:
        energy += tangential_spring_energy(params[a, b, _KT], history, k)
    elif model[2] == _MINDLIN:
        kt = tangential_mindlin_stiffness(params[a, b, _G], math.sqrt(r_eff * overlap))
        energy += tangential_spring_energy(kt, history, k)
    return energy


@scalar
def contact_release(model, params, a, b, history, k):
    """Energy [J] left in the tangential spring when a contact opens; it is lost with
    the history and counts as tangential dissipation.  (The Mindlin stiffness vanishes
    with the overlap, so its spring holds nothing at separation.)"""
    if model[2] == _CUNDALL:
        return tangential_spring_energy(params[a, b, _KT], history, k)
    return 0.0
