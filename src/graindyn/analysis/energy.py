"""Energies [J]: kinetic (translational, rotational), gravitational, elastic energy
stored in contacts, and the dissipation the loop accumulates, for an energy balance

    E_kin + E_rot + E_grav + E_elastic + D_normal + D_tangential - W_walls = const.
"""
import numpy as np

from .._jit import kernel
from ..core.neighbors import min_image
from ..core.walls import wall_distance
from ..physics.contact import contact_energy


@kernel
def _elastic(model, params, positions, radii, materials, periodic_flag, periodic_length, start,
             partners, history, wall_kind, wall_geometry, wall_offset, wall_material,
             wall_start, wall_ids, wall_history):
    total = 0.0
    for i in range(radii.size):
        for k in range(start[i], start[i + 1]):
            j = partners[k]
            d2 = 0.0
            for d in range(3):
                dx = min_image(positions[i, d] - positions[j, d], periodic_flag[d],
                               periodic_length[d])
                d2 += dx * dx
            rsum = radii[i] + radii[j]
            overlap = rsum - np.sqrt(d2)
            if overlap > 0.0:
                total += contact_energy(model, params, materials[i], materials[j], overlap,
                                        radii[i] * radii[j] / rsum, history, k)
        for q in range(wall_start[i], wall_start[i + 1]):
            w = wall_ids[q]
            dist, nx, ny, nz = wall_distance(wall_kind, wall_geometry, wall_offset, w,
                                             positions[i, 0], positions[i, 1], positions[i, 2])
            overlap = radii[i] - dist
            if overlap > 0.0:
                total += contact_energy(model, params, materials[i], wall_material[w], overlap,
                                        radii[i], wall_history, q)
    return total


def elastic_energy(sim):
    """Energy stored in the normal and tangential springs of all contacts [J]."""
    s, w, p, c = sim.state, sim.walls, sim.pairs, sim.wall_contacts
    return float(_elastic(sim.model_ids, sim.params, s.positions, s.radii, s.materials,
                          w.periodic_flag, w.periodic_length, p[0], p[1], p[2], w.kind,
                          w.geometry, w.offset, w.material, c[0], c[1], c[2]))


def kinetic_energy(state):
    """(translational, rotational) kinetic energy of the free grains [J]."""
    free = state.fixed == 0
    v2 = np.einsum("ij,ij->i", state.velocities, state.velocities)
    w2 = np.einsum("ij,ij->i", state.angular_velocities, state.angular_velocities)
    return (float(0.5 * np.sum(state.masses[free] * v2[free])),
            float(0.5 * np.sum(state.inertias[free] * w2[free])))


def gravitational_energy(state, gravity):
    """-sum m g.r of the free grains [J] (zero at the origin)."""
    free = state.fixed == 0
    return float(-np.sum(state.masses[free] * (state.positions[free] @ np.asarray(gravity))))


def energy_budget(sim):
    """Every term of the energy balance [J] and their sum ``total`` (constant up to the
    integrator's error: kinetic + rotational + gravitational + elastic + dissipated
    - wall work)."""
    from ..core import loop

    translational, rotational = kinetic_energy(sim.state)
    out = {"kinetic": translational, "rotational": rotational,
           "gravitational": gravitational_energy(sim.state, sim.clock[loop.GX:loop.GZ + 1]),
           "elastic": elastic_energy(sim),
           "dissipated_normal": sim.dissipated["normal"],
           "dissipated_tangential": sim.dissipated["tangential"],
           "wall_work": sim.wall_work}
    out["total"] = (translational + rotational + out["gravitational"] + out["elastic"]
                    + out["dissipated_normal"] + out["dissipated_tangential"] - out["wall_work"])
    return out
