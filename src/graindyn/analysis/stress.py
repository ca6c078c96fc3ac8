"""Stress from contact dipoles (Love-Weber), compression positive [Pa]:

    sigma_ab = (1/V) sum_contacts f_a l_b,

f the force on grain i and l the branch vector from j (or the wall contact point) to i.
"""
import numpy as np


def contact_stress(sim, volume, select=None):
    """(3, 3) stress tensor [Pa] of the contacts between grains selected by the boolean
    mask ``select`` (default all), averaged over ``volume`` [m^3] (2D: area [m^2]).
    A pair counts with weight 1/2 for each selected member; wall contacts count fully."""
    s = sim.state
    select = np.ones(s.n, bool) if select is None else np.asarray(select, bool)
    i, j, f = sim.contacts()
    branch = s.positions[i] - s.positions[j]
    w = sim.walls
    for d in range(3):
        if w.periodic_flag[d]:
            length = w.periodic_length[d]
            branch[:, d] -= length * np.floor(branch[:, d] / length + 0.5)
    weight = 0.5 * (select[i].astype(float) + select[j])
    sigma = np.einsum("k,ka,kb->ab", weight, f, branch)
    gi, gw, gf = sim.wall_contacts_active()
    if gi.size:
        dist, normal = w.distances(s.positions[gi], gw)
        lever = dist[:, None] * normal
        sigma += np.einsum("k,ka,kb->ab", select[gi].astype(float), gf, lever)
    return sigma / volume
