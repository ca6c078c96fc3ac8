"""The energy balance of a run [J], from the energies its engine reports
(core.engine.ENERGIES):

    E_kin + E_rot + E_grav + E_elastic + D_normal + D_tangential - W_walls = const.

and, for a settling that does not end, which grains hold the kinetic energy left.
"""
import math

import numpy as np


def energy_budget(engine):
    """Every energy of ``engine.energies()`` [J] and their balance ``total``, constant up
    to the engine's error (kinetic + rotational + gravitational + elastic + dissipated
    - wall work)."""
    out = engine.energies()
    out["total"] = (out["kinetic"] + out["rotational"] + out["gravitational"]
                    + out["elastic"] + out["dissipated_normal"]
                    + out["dissipated_tangential"] - out["wall_work"])
    return out


def settling_ratio(state, gravity):
    """E_kin / E_pot [-] as the settling criterion reads it (core.triggers
    .EnergyRatioBelow, Karrech et al. Sec. 3): translational plus rotational kinetic
    energy over the gravitational energy above the lowest grain, free grains only;
    inf without gravity or height."""
    free = state.fixed == 0
    g = np.asarray(gravity, dtype=float)
    g_norm = float(np.linalg.norm(g))
    kinetic = float(np.sum(kinetic_energies(state)[free]))
    if g_norm == 0.0 or not free.any():
        return math.inf
    height = -(state.positions[free] @ g) / g_norm
    potential = float(np.sum(state.masses[free] * g_norm * (height - height.min())))
    return kinetic / potential if potential > 0.0 else math.inf


def kinetic_energies(state):
    """Each grain's translational plus rotational kinetic energy [J], (N,)."""
    return (0.5 * state.masses * np.sum(state.velocities**2, axis=1)
            + 0.5 * state.inertias * np.sum(state.angular_velocities**2, axis=1))


def kinetic_holders(engine, share=0.9, most=10):
    """The fewest grains that hold ``share`` of the free grains' kinetic energy, at most
    ``most`` (none when the energy is spread over more: the bed as a whole still moves),
    largest first: dicts of the grain's index, its translational and rotational
    energies [J], its grain, wall and image contacts (symmetry planes: a grain never
    slides on an image, which mirrors its motion), ``surface_speed_m_s`` |v| + R |w|
    [m/s] and ``slip_m_s``, the largest sliding speed [m/s] at its grain contacts (the
    tangential part of the contact points' relative velocity).  A grain that spins
    about the line through its contacts, or rolls on another, slips nowhere; under a
    contact law without rolling or twisting resistance it then keeps its energy, and a
    settling criterion on E_kin/E_pot is never met."""
    s = engine.state
    energy = kinetic_energies(s)
    energy[s.fixed != 0] = 0.0
    total = float(energy.sum())
    if total <= 0.0:
        return []
    order = np.argsort(energy)[::-1]
    count = int(np.searchsorted(np.cumsum(energy[order]), share * total)) + 1
    if count > most:
        return []
    contacts, walls = engine.contacts(), engine.wall_contacts()
    images = engine.image_contacts().grain if hasattr(engine, "image_contacts") \
        else np.zeros(0, np.int64)
    slip = _slip_speeds(s, contacts)
    holders = []
    for i in order[:count]:
        mine = (contacts.i == i) | (contacts.j == i)
        holders.append({
            "grain": int(i),
            "translational_J": float(0.5 * s.masses[i] * np.sum(s.velocities[i]**2)),
            "rotational_J": float(0.5 * s.inertias[i] * np.sum(s.angular_velocities[i]**2)),
            "grain_contacts": int(np.count_nonzero(mine)),
            "wall_contacts": int(np.count_nonzero(walls.grain == i)),
            "image_contacts": int(np.count_nonzero(images == i)),
            "surface_speed_m_s": float(np.linalg.norm(s.velocities[i]) + s.radii[i]
                                       * np.linalg.norm(s.angular_velocities[i])),
            "slip_m_s": float(slip[mine].max()) if mine.any() else 0.0})
    return holders


def _slip_speeds(state, contacts):
    """The sliding speed [m/s] at each grain-grain contact: the tangential part of the
    relative velocity of the two contact points (v + w x b for each grain, b its branch
    vector)."""
    v, w = state.velocities, state.angular_velocities
    relative = (v[contacts.i] + np.cross(w[contacts.i], contacts.branch_i)
                - v[contacts.j] - np.cross(w[contacts.j], contacts.branch_j))
    n = contacts.normal
    tangential = relative - np.sum(relative * n, axis=1)[:, None] * n
    return np.linalg.norm(tangential, axis=1)
