"""Stress from contact dipoles (Love-Weber), compression positive [Pa]:

    sigma_ab = (1/V) sum_contacts f_a l_b,

f the force on grain i and l the branch vector from j (or the wall contact point) to i:
l = branch_j - branch_i for a pair, -branch for a wall contact (core.engine.Contacts).
"""
import numpy as np


def contact_stress(engine, volume, select=None):
    """(3, 3) stress tensor [Pa] of the contacts of ``engine`` (core.engine) between
    grains selected by the boolean mask ``select`` (default all), averaged over
    ``volume`` [m^3] (2D: area [m^2]).  A pair counts with weight 1/2 for each selected
    member; wall contacts count fully."""
    select = np.ones(engine.state.n, bool) if select is None else np.asarray(select, bool)
    pairs = engine.contacts()
    weight = 0.5 * (select[pairs.i].astype(float) + select[pairs.j])
    sigma = np.einsum("k,ka,kb->ab", weight, pairs.force, pairs.branch_j - pairs.branch_i)
    walls = engine.wall_contacts()
    sigma -= np.einsum("k,ka,kb->ab", select[walls.grain].astype(float), walls.force,
                       walls.branch)
    return sigma / volume
