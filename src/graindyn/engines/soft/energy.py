"""The elastic energy stored in a soft-particle simulation's contacts [J]
(Simulation.energies gathers it with the kinetic and gravitational energies of
core.engine and the dissipation the loop accumulates).
"""
import numpy as np

from ..._jit import kernel
from ...core.neighbors import min_image
from ...core.symmetry import MASKS, image_separation
from ...core.walls import wall_distance
from ...physics.contact import contact_energy


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


@kernel
def _elastic_images(model, params, positions, radii, materials, periodic_flag,
                    periodic_length, at, start, codes, history):
    """Half the energy of each touching image contact [J] (image_contacts.py: the other
    half is the mirror half's)."""
    total = 0.0
    for i in range(radii.size):
        for q in range(start[i], start[i + 1]):
            j = codes[q] // MASKS
            dx, dy, dz = image_separation(i, codes[q], positions, at, periodic_flag,
                                          periodic_length)
            rsum = radii[i] + radii[j]
            overlap = rsum - np.sqrt(dx * dx + dy * dy + dz * dz)
            if overlap > 0.0:
                total += 0.5 * contact_energy(model, params, materials[i], materials[j],
                                              overlap, radii[i] * radii[j] / rsum, history, q)
    return total


def elastic_energy(model_ids, params, state, walls, pairs, wall_pairs, images=None):
    """Energy stored in the normal and tangential springs of all listed contacts [J]
    (physics.contact.contact_energy of each touching pair and wall contact, and half of
    each image contact's); pairs, wall_pairs and images : bundles.Pairs, WallPairs and
    Images (Simulation.pairs, wall_pairs, images)."""
    total = float(_elastic(model_ids, params, state.positions, state.radii, state.materials,
                           walls.periodic_flag, walls.periodic_length, pairs.start,
                           pairs.partners, pairs.history, walls.kind, walls.geometry,
                           walls.offset, walls.material, wall_pairs.start, wall_pairs.ids,
                           wall_pairs.history))
    if images is not None and images.start[-1] > 0:
        total += float(_elastic_images(model_ids, params, state.positions, state.radii,
                                       state.materials, walls.periodic_flag,
                                       walls.periodic_length, images.at, images.start,
                                       images.ids, images.history))
    return total

