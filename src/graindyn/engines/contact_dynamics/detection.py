"""Candidate contacts of rigid grains: the core's neighbour lists (core/neighbors.py)
with a skin of ``gap + margin``, rebuilt when some grain or wall may have moved more than
half the margin; every step, the gap and normal of each listed pair and grain-wall
candidate.  A listed contact whose gap is below ``gap`` [m] takes part in the step's
solve, so a contact that closes within a step is seen at its start.

The lists' per-contact history is the contact impulse (3 values, global frame [N s]) of
the last step: the solver's warm start, carried over rebuilds pair by pair by the core
(neighbors.carry_row).
"""
from typing import NamedTuple

import math

import numpy as np

from ..._jit import kernel
from ...core.neighbors import min_image, rebuild
from ...core.walls import wall_distance


class Lists(NamedTuple):
    """The pair and wall-candidate lists (CSR, as core/neighbors.py builds them) with
    the per-contact state of the solver.

    start : (N + 1,) int64;  partners : (P,) uint32 grain j of each listed pair (i < j)
    impulses : (P, 6) float64 the last step's impulse on grain i [N s] (columns 0-2) and
      rolling couple impulse on grain i [N m s] (3-5), global frame (IMPULSE_WIDTH)
    owner : (P,) uint32 grain i of each listed pair (written by each rebuild)
    gap : (P,) float64 [m] |r_i - r_j| - R_i - R_j at the start of the step
    normal : (P, 3) unit normal from j to i
    wall_start : (N + 1,) int64;  wall_ids : (Q,) uint32 wall of each candidate
    wall_impulses : (Q, 6) impulse [N s] and couple [N m s] on the grain;  wall_owner : (Q,) uint32 grain
    wall_gap : (Q,) [m] distance to the wall minus R;  wall_normal : (Q, 3) from the wall
    scratch_* : work space of the rebuild (same shapes);  reverse_start, reverse_pairs:
      the pairs by their second grain (written by the core's rebuild, unused here)
    """
    start: np.ndarray
    partners: np.ndarray
    impulses: np.ndarray
    owner: np.ndarray
    gap: np.ndarray
    normal: np.ndarray
    wall_start: np.ndarray
    wall_ids: np.ndarray
    wall_impulses: np.ndarray
    wall_owner: np.ndarray
    wall_gap: np.ndarray
    wall_normal: np.ndarray
    scratch_start: np.ndarray
    scratch_partners: np.ndarray
    scratch_impulses: np.ndarray
    scratch_wall_start: np.ndarray
    scratch_wall_ids: np.ndarray
    scratch_wall_impulses: np.ndarray
    reverse_start: np.ndarray
    reverse_pairs: np.ndarray


# columns of the impulses kept per contact: the impulse (3) and the rolling couple (3)
IMPULSE_WIDTH = 6


def new_lists(n, pair_capacity, wall_capacity, old=None):
    """Lists for n grains with room for the given numbers of pairs and wall candidates,
    keeping the lists of ``old`` (a Lists) when given."""
    arrays = dict(
        start=np.zeros(n + 1, np.int64), partners=np.zeros(pair_capacity, np.uint32),
        impulses=np.zeros((pair_capacity, IMPULSE_WIDTH)),
        owner=np.zeros(pair_capacity, np.uint32),
        gap=np.zeros(pair_capacity), normal=np.zeros((pair_capacity, 3)),
        wall_start=np.zeros(n + 1, np.int64), wall_ids=np.zeros(wall_capacity, np.uint32),
        wall_impulses=np.zeros((wall_capacity, IMPULSE_WIDTH)),
        wall_owner=np.zeros(wall_capacity, np.uint32), wall_gap=np.zeros(wall_capacity),
        wall_normal=np.zeros((wall_capacity, 3)),
        scratch_start=np.zeros(n + 1, np.int64),
        scratch_partners=np.zeros(pair_capacity, np.uint32),
        scratch_impulses=np.zeros((pair_capacity, IMPULSE_WIDTH)),
        scratch_wall_start=np.zeros(n + 1, np.int64),
        scratch_wall_ids=np.zeros(wall_capacity, np.uint32),
        scratch_wall_impulses=np.zeros((wall_capacity, IMPULSE_WIDTH)),
        reverse_start=np.zeros(n + 1, np.int64),
        reverse_pairs=np.zeros(pair_capacity, np.uint32))
    if old is not None:
        for name in ("start", "wall_start"):
            arrays[name][:] = getattr(old, name)
        m, q = int(old.start[n]), int(old.wall_start[n])
        for name in ("partners", "impulses", "owner", "gap", "normal"):
            arrays[name][:m] = getattr(old, name)[:m]
        for name in ("wall_ids", "wall_impulses", "wall_owner", "wall_gap", "wall_normal"):
            arrays[name][:q] = getattr(old, name)[:q]
    return Lists(**arrays)


@kernel
def relist(positions, radii, skin, periodic_flag, periodic_lo, periodic_length, lists,
           wall_kind, wall_geometry, wall_offset, reference_positions, reference_offset):
    """Rebuild the lists (neighbors.rebuild: positions wrapped into the periodic box,
    impulses carried over pair by pair); returns (pairs needed, wall candidates needed),
    nothing but the wrapped positions changed when either exceeds its capacity."""
    needed, wall_needed = rebuild(
        positions, radii, skin, periodic_flag, periodic_lo, periodic_length,
        lists.start, lists.partners, lists.impulses, lists.scratch_start,
        lists.scratch_partners, lists.scratch_impulses, lists.reverse_start,
        lists.reverse_pairs, wall_kind, wall_geometry, wall_offset, lists.wall_start,
        lists.wall_ids, lists.wall_impulses, lists.scratch_wall_start,
        lists.scratch_wall_ids, lists.scratch_wall_impulses, reference_positions,
        reference_offset)
    if needed <= lists.partners.size and wall_needed <= lists.wall_ids.size:
        lists.owner[:needed] = lists.scratch_partners[:needed]
        lists.wall_owner[:wall_needed] = lists.scratch_wall_ids[:wall_needed]
    return needed, wall_needed


@kernel
def moved_beyond(positions, reference_positions, offset, reference_offset, velocity, dt,
                 margin):
    """True when some grain plus some wall may have moved, by the end of the coming
    step, more than ``margin`` [m] nearer each other than at the last rebuild: twice the
    largest grain displacement plus the largest wall displacement (and |v| dt of each)."""
    grain = 0.0
    for i in range(positions.shape[0]):
        d2 = 0.0
        for d in range(3):
            d2 += (positions[i, d] - reference_positions[i, d]) ** 2
        grain = max(grain, math.sqrt(d2))
    wall = 0.0
    for w in range(offset.shape[0]):
        d2 = 0.0
        v2 = 0.0
        for d in range(3):
            d2 += (offset[w, d] - reference_offset[w, d]) ** 2
            v2 += velocity[w, d] ** 2
        wall = max(wall, math.sqrt(d2) + math.sqrt(v2) * dt)
    return 2.0 * grain + wall > margin


@kernel
def contact_geometry(positions, radii, periodic_flag, periodic_length, lists, wall_kind,
                     wall_geometry, wall_offset):
    """Gap [m] and unit normal of every listed pair (from j to i, minimum image) and
    grain-wall candidate (from the wall to the grain), at the present positions."""
    n = radii.size
    for k in range(lists.start[n]):
        i = lists.owner[k]
        j = lists.partners[k]
        d2 = 0.0
        for d in range(3):
            lists.normal[k, d] = min_image(positions[i, d] - positions[j, d],
                                           periodic_flag[d], periodic_length[d])
            d2 += lists.normal[k, d] ** 2
        dist = math.sqrt(d2)
        lists.gap[k] = dist - radii[i] - radii[j]
        for d in range(3):
            lists.normal[k, d] /= dist
    for q in range(lists.wall_start[n]):
        i = lists.wall_owner[q]
        dist, nx, ny, nz = wall_distance(wall_kind, wall_geometry, wall_offset,
                                         lists.wall_ids[q], positions[i, 0], positions[i, 1],
                                         positions[i, 2])
        lists.wall_gap[q] = dist - radii[i]
        lists.wall_normal[q, 0] = nx
        lists.wall_normal[q, 1] = ny
        lists.wall_normal[q, 2] = nz
