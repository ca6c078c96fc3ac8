"""One contact, all modes: the integer-id dispatcher over the registered sub-models.

Order (as LAMMPS GRANULAR): elastic normal force, damping, clamp to repulsive,
tangential law capped by the normal force, rolling and twisting couples.  Law ids,
table columns and history offsets come from physics/registry.py; ``model`` is the
int array of ContactModel.ids().
"""
import math

from .._jit import scalar
from .damping import (damping_karrech_coefficient, damping_linear_coefficient,
                      damping_tsuji_coefficient, damping_viscoelastic_coefficient)
from .indexing import hrow, prow
from .normal import (normal_hertz_energy, normal_hertz_stiffness, normal_hooke_energy,
                     normal_walton_braun_energy, normal_walton_braun_force,
                     normal_walton_braun_silo_force)
from .registry import (COL, DAMPING, HISTORY, LIMIT_DAMPING, NORMAL, PLANAR, ROLLING,
                       TANGENTIAL, TWISTING)
from .rolling import rolling_constant_torque
from .tangential import (tangential_coulomb_force, tangential_mindlin_rescale,
                         tangential_mindlin_stiffness, tangential_oquendo_force,
                         tangential_oquendo_literal_force, tangential_planar_spring_force,
                         tangential_spring_energy, tangential_spring_force)
from .twisting import twisting_constant_torque, twisting_oquendo_torque, twisting_spring_torque

_HOOKE = NORMAL["hooke"]
_HERTZ = NORMAL["hertz"]
_WALTON_BRAUN = NORMAL["walton_braun"]
_WALTON_BRAUN_SILO = NORMAL["walton_braun_silo"]
_LINEAR = DAMPING["linear"]
_VISCOELASTIC = DAMPING["viscoelastic"]
_TSUJI = DAMPING["tsuji"]
_KARRECH_DAMPING = DAMPING["karrech"]
_COULOMB = TANGENTIAL["coulomb"]
_CUNDALL = TANGENTIAL["cundall_strack"]
_MINDLIN = TANGENTIAL["mindlin"]
_KARRECH = TANGENTIAL["karrech"]
_OQUENDO = TANGENTIAL["oquendo"]
_OQUENDO_LITERAL = TANGENTIAL["oquendo_literal"]
_ROLL_NONE = ROLLING["none"]
_ROLL_CONSTANT = ROLLING["constant"]
_ROLL_EPSD = ROLLING["epsd"]
_TWIST_NONE = TWISTING["none"]
_TWIST_OQUENDO = TWISTING["oquendo"]
_TWIST_CONSTANT = TWISTING["constant"]
_TWIST_EPSD = TWISTING["epsd"]
# history offsets in the model array
_H_NORMAL = HISTORY
_H_TANGENTIAL = HISTORY + 2
_H_ROLLING = HISTORY + 3
_H_TWISTING = HISTORY + 4
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
_MU_S = COL["friction_static"]
_MU_R = COL["friction_rolling"]
_EN = COL["restitution"]
_SLIP = COL["slip_threshold"]
_GAMMA_NT = COL["gamma_nt"]
_ALPHA_N = COL["alpha_n"]
_ALPHA_T = COL["alpha_t"]
_K_ROLL = COL["rolling_stiffness"]
_C_ROLL = COL["rolling_damping"]
_MU_TW = COL["friction_twisting"]
_K_TW = COL["twisting_stiffness"]
_C_TW = COL["twisting_damping"]
_BETA_I = COL["inertia_ratio"]


@scalar
def _spring(model, kt, eta_t, mu, fn, cap, nx, ny, nz, vtx, vty, vtz, history, k, h, dt):
    """The capped tangential spring of a contact: its vector form
    (tangential_spring_force), or for disks (the model's planar flag) its scalar 2D form
    (tangential_planar_spring_force, Perez Eq. 20)."""
    if model[PLANAR] != 0:
        return tangential_planar_spring_force(kt, eta_t, mu, fn, cap, nx, ny, vtx, vty,
                                              history, k, h, dt)
    return tangential_spring_force(kt, eta_t, mu, fn, cap, nx, ny, nz, vtx, vty, vtz,
                                   history, k, h, dt)


@scalar
def _rolling_radius(lever_i, lever_j):
    """R'_ij = R'_i R'_j / (R'_i + R'_j) [m] (Oquendo Eq. 7); R'_i against a wall
    (lever_j = 0, R'_j infinite).  Worked out only by the laws that use it: a division
    every contact evaluated one at a time pays for whether it is used or not."""
    return lever_i if lever_j == 0.0 else lever_i * lever_j / (lever_i + lever_j)


@scalar
def contact_force(model, params, a, b, overlap, r_eff, lever_i, lever_j, m_eff, nx, ny, nz, vn,
                  vtx, vty, vtz, wx, wy, wz, history, k, dt):
    """Force on grain i and couple on i of one contact with overlap > 0.

    model : (12,) int ids (normal, damping, tangential, rolling, twisting), the
        limit_damping flag (1 keeps the normal force repulsive, Perez Eq. 14, 17; 0
        lets the dashpot pull at the end of a contact, the LAMMPS default), the
        five history offsets and the planar flag (disks: the springs of cundall_strack,
        mindlin and karrech in their scalar 2D form)
    params[prow(a, b, col)] : the parameters of the material pair (a, b)
    (physics/indexing.py);  overlap [m];
    r_eff = R* [m];  lever_i, lever_j = R'_i, R'_j [m], the corrected radii of Oquendo
    Eq. 3-4 (lever_j = 0 for a wall), from which the laws that use it take R'_ij
    (_rolling_radius);  m_eff [kg]
    n : unit normal from j to i;  vn = v_rel.n [m/s] (negative when approaching)
    v_t : tangential relative velocity of i at the contact point [m/s] (Oquendo Eq. 4)
    w : relative angular velocity w_i - w_j [rad/s]
    history[hrow(k, c)] : this contact's history values (physics/indexing.py), updated
    in place;  dt [s]
    (Whole arrays and indices are passed rather than row views: a view costs two
    atomic reference-count updates per contact in numba.)
    Returns (f_n >= 0 [N], f_t (3) [N], couple M (3) [N m] on i (-M on j), normal
    and tangential energy dissipated [J]; rolling and twisting losses count as
    tangential).
    """
    radius = math.sqrt(r_eff * overlap)  # Hertz contact radius a [m]
    normal = model[0]
    lost_n = 0.0
    if normal == _HOOKE:
        stiffness = params[prow(a, b, _KN)]
        tangent = stiffness
        f_el = stiffness * overlap  # Perez Eq. 14
    elif normal == _HERTZ:
        stiffness = normal_hertz_stiffness(radius, params[prow(a, b, _E)])
        tangent = 1.5 * stiffness
        f_el = stiffness * overlap  # Perez Eq. 17, Oquendo Eq. 1, Karrech Eq. 5
    elif normal == _WALTON_BRAUN:
        stiffness = params[prow(a, b, _KN)]
        tangent = stiffness
        f_el, lost_n = normal_walton_braun_force(overlap, stiffness, params[prow(a, b, _EN)],
                                                 history, k, model[_H_NORMAL])
    else:
        stiffness = params[prow(a, b, _KN)]
        tangent = stiffness
        f_el, lost_n = normal_walton_braun_silo_force(overlap, stiffness, params[prow(a, b, _EN)],
                                                      history, k, model[_H_NORMAL])
    damping = model[1]
    if damping == _LINEAR:
        c = damping_linear_coefficient(m_eff, params[prow(a, b, _KN)], params[prow(a, b, _BETA)],
                                       params[prow(a, b, _GAMMA0)])
    elif damping == _VISCOELASTIC:
        c = damping_viscoelastic_coefficient(m_eff, overlap, params[prow(a, b, _GAMMA_N)])
    elif damping == _TSUJI:
        c = damping_tsuji_coefficient(m_eff, stiffness, params[prow(a, b, _ALPHA)])
    elif damping == _KARRECH_DAMPING:
        c = damping_karrech_coefficient(m_eff, tangent, params[prow(a, b, _ALPHA_N)])
    else:
        c = 0.0
    rate = -vn
    fn = f_el + c * rate
    if fn < 0.0 and model[LIMIT_DAMPING] != 0:
        fn = 0.0
    dissipated_n = (fn - f_el) * rate * dt + lost_n
    cap = abs(fn)  # the friction limit uses |f_n| when the dashpot pulls (as LAMMPS)
    tangential = model[2]
    ht = model[_H_TANGENTIAL]
    mx = my = mz = 0.0
    # rolling part of the relative rotation (tangent-plane component) and twist rate,
    # for the laws that use them
    wn = wrx = wry = wrz = 0.0
    if tangential == _OQUENDO or tangential == _OQUENDO_LITERAL or model[3] != _ROLL_NONE \
            or model[4] != _TWIST_NONE:
        wn = wx * nx + wy * ny + wz * nz
        wrx = wx - wn * nx
        wry = wy - wn * ny
        wrz = wz - wn * nz
    if tangential == _COULOMB:
        ftx, fty, ftz, dissipated_t = tangential_coulomb_force(
            params[prow(a, b, _MU)], cap, vtx, vty, vtz, dt)
    elif tangential == _CUNDALL:
        ftx, fty, ftz, dissipated_t = _spring(
            model, params[prow(a, b, _KT)], params[prow(a, b, _XT)] * c,
            params[prow(a, b, _MU)], cap, 0, nx, ny, nz, vtx, vty, vtz, history, k, ht, dt)
    elif tangential == _MINDLIN or tangential == _KARRECH or tangential == _OQUENDO:
        fresh = history[hrow(k, ht + 3)] == 0.0      # no contact radius stored yet: first touch
        kt, lost_t = tangential_mindlin_rescale(params[prow(a, b, _G)], radius, history, k, ht)
        if tangential == _MINDLIN:
            ftx, fty, ftz, dissipated_t = _spring(
                model, kt, params[prow(a, b, _XT)] * c, params[prow(a, b, _MU)], cap, 0, nx,
                ny, nz, vtx, vty, vtz, history, k, ht, dt)
        elif tangential == _KARRECH:
            ftx, fty, ftz, dissipated_t = _spring(
                model, kt, damping_karrech_coefficient(m_eff, kt, params[prow(a, b, _ALPHA_T)]),
                params[prow(a, b, _MU)], cap, 1, nx, ny, nz, vtx, vty, vtz, history, k, ht, dt)
        else:
            threshold = params[prow(a, b, _SLIP)]
            r_roll = _rolling_radius(lever_i, lever_j)
            ftx, fty, ftz, dissipated_t, sliding = tangential_oquendo_force(
                kt, params[prow(a, b, _XT)] * c, params[prow(a, b, _MU)],
                params[prow(a, b, _MU_S)], threshold, fresh, cap, nx, ny, nz, vtx, vty, vtz,
                history, k, ht, dt)
            # rolling (Oquendo Eq. 7-9): not sliding and R'_ij |w_r| above the threshold;
            # the couple evaluated for every contact and kept by selects (SIMD lanes, as
            # tangential_oquendo_force)
            rolls = (sliding == 0.0) & (
                r_roll * math.sqrt(wrx * wrx + wry * wry + wrz * wrz) > threshold)
            cx, cy, cz, lost_r = rolling_constant_torque(
                params[prow(a, b, _MU_R)] * r_roll * cap, wrx, wry, wrz, dt)
            mx = cx if rolls else 0.0
            my = cy if rolls else 0.0
            mz = cz if rolls else 0.0
            dissipated_t = dissipated_t + lost_r if rolls else dissipated_t
        dissipated_t += lost_t
    elif tangential == _OQUENDO_LITERAL:
        mu_r = params[prow(a, b, _MU_R)]
        r_roll = _rolling_radius(lever_i, lever_j)
        ftx, fty, ftz, dissipated_t, regime = tangential_oquendo_literal_force(
            params[prow(a, b, _MU)], params[prow(a, b, _MU_S)], mu_r,
            params[prow(a, b, _SLIP)], params[prow(a, b, _BETA_I)],
            cap, r_roll, m_eff, nx, ny, nz, vtx, vty, vtz,
            wrx, wry, wrz, history, k, ht, dt)
        # rolling: the couple of Eq. 8-9 (see the law), kept by selects (SIMD lanes)
        rolls = regime == 2.0
        cx, cy, cz, lost_r = rolling_constant_torque(mu_r * r_roll * cap, wrx, wry, wrz, dt)
        mx = cx if rolls else 0.0
        my = cy if rolls else 0.0
        mz = cz if rolls else 0.0
        dissipated_t = dissipated_t + lost_r if rolls else dissipated_t
    else:
        ftx = fty = ftz = dissipated_t = 0.0
    rolling = model[3]
    if rolling == _ROLL_CONSTANT:
        rx, ry, rz, lost_r = rolling_constant_torque(params[prow(a, b, _MU_R)] * r_eff * cap, wrx,
                                                     wry, wrz, dt)
    elif rolling == _ROLL_EPSD:
        r2 = r_eff * r_eff
        rx, ry, rz, lost_r = tangential_spring_force(
            params[prow(a, b, _K_ROLL)] * r2, params[prow(a, b, _C_ROLL)] * r2,
            params[prow(a, b, _MU_R)] * r_eff, cap, 2, nx, ny, nz, wrx, wry, wrz, history, k,
            model[_H_ROLLING], dt)
    else:
        rx = ry = rz = lost_r = 0.0
    twisting = model[4]
    if twisting == _TWIST_OQUENDO:
        tw, lost_w = twisting_oquendo_torque(params[prow(a, b, _GAMMA_NT)], m_eff, r_eff,
                                             overlap, wn, dt)
    elif twisting == _TWIST_CONSTANT:
        tw, lost_w = twisting_constant_torque(params[prow(a, b, _MU_TW)] * radius * cap, wn, dt)
    elif twisting == _TWIST_EPSD:
        tw, lost_w = twisting_spring_torque(params[prow(a, b, _K_TW)], params[prow(a, b, _C_TW)],
                                            params[prow(a, b, _MU_TW)] * radius * cap, wn,
                                            history, k, model[_H_TWISTING], dt)
    else:
        tw = lost_w = 0.0
    return (fn, ftx, fty, ftz, mx + rx + tw * nx, my + ry + tw * ny, mz + rz + tw * nz,
            dissipated_n, dissipated_t + lost_r + lost_w)


@scalar
def _spring_energy(model, params, a, b, r_eff, history, k):
    """Energy [J] held in the history springs: tangential, rolling and twisting."""
    energy = 0.0
    tangential = model[2]
    ht = model[_H_TANGENTIAL]
    if tangential == _CUNDALL:
        energy += tangential_spring_energy(params[prow(a, b, _KT)], history, k, ht)
    elif tangential == _MINDLIN or tangential == _KARRECH or tangential == _OQUENDO:
        kt = tangential_mindlin_stiffness(params[prow(a, b, _G)], history[hrow(k, ht + 3)])
        energy += tangential_spring_energy(kt, history, k, ht)
    if model[3] == _ROLL_EPSD:
        energy += tangential_spring_energy(params[prow(a, b, _K_ROLL)] * r_eff * r_eff, history, k,
                                           model[_H_ROLLING])
    if model[4] == _TWIST_EPSD:
        theta = history[hrow(k, model[_H_TWISTING])]
        energy += 0.5 * params[prow(a, b, _K_TW)] * theta * theta
    return energy


@scalar
def contact_energy(model, params, a, b, overlap, r_eff, history, k):
    """Elastic energy [J] stored in one contact: normal spring plus the history springs
    (the Mindlin spring with the stiffness of its last evaluation).  For the
    Walton-Braun laws, the energy unloading would give back."""
    if overlap <= 0.0:
        return 0.0
    normal = model[0]
    if normal == _HOOKE:
        energy = normal_hooke_energy(overlap, params[prow(a, b, _KN)])
    elif normal == _HERTZ:
        energy = normal_hertz_energy(overlap, r_eff, params[prow(a, b, _E)])
    elif normal == _WALTON_BRAUN:
        energy = normal_walton_braun_energy(overlap, params[prow(a, b, _KN)],
                                            params[prow(a, b, _EN)],
                                            history, k, model[_H_NORMAL])
    else:
        energy = normal_hooke_energy(overlap,
                                     params[prow(a, b, _EN)] ** 2 * params[prow(a, b, _KN)])
    return energy + _spring_energy(model, params, a, b, r_eff, history, k)


@scalar
def contact_release(model, params, a, b, r_eff, history, k):
    """Energy [J] left in the history springs (tangential, rolling, twisting) when a
    contact opens; it is lost with the history and counts as tangential dissipation."""
    return _spring_energy(model, params, a, b, r_eff, history, k)
