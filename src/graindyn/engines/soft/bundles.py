"""The bundles of arrays the soft engine hands to its compiled kernels, by name.

Each bundle is a ``typing.NamedTuple`` of arrays: numba compiles a namedtuple of arrays
in nopython mode as it does a plain tuple (the same machine code; ``grains.radii`` is
resolved at compile time), and caches it on disk, the class being importable from here.
Kernels read the fields by name, never by position; bundles are built by keyword.
Shapes: N grains, W walls, P pair slots (the pair list's capacity), Q wall-contact
slots, H history values per contact (Simulation.history_size: the model's, then the
touching mark, contacts.touch), B blocks of grains
(contacts.block_count).  Lists are CSR: the contacts grain i lists are slots
start[i]..start[i + 1] - 1.

The field names of Pairs, WallPairs and Images are also the names of their arrays in a
checkpoint ("pairs/start", "wall_contacts/ids": Simulation.snapshot); the GPU keys its
device arrays by (group, field name) (engines/soft/gpu/layout.py).
"""
from typing import NamedTuple

import numpy as np


class Grains(NamedTuple):
    """The grains as the loop sees them: the State's arrays plus the loop's own.

    positions, velocities : (N, 3) float64 [m], [m/s]
    angular_velocities : (N, 3) float64 [rad/s]
    orientations : (N, 4) float64 unit quaternions (w, x, y, z), or (0, 4) when the
      simulation does not turn them (Simulation(orientations=False))
    forces, torques : (N, 3) float64 [N], [N m] of the last force evaluation
    accelerations, angular_accelerations : (N, 3) float64 [m/s^2], [rad/s^2]
    radii, masses, inertias : (N,) float64 [m], [kg], [kg m^2]
    materials : (N,) int32 material index;  fixed : (N,) int8, 1 for grains held in place
    reference_positions : (N, 3) float64 [m] positions at the last neighbour build
    max_overlap : (N,) float64 largest overlap / smaller radius [-] since the last check
      (contacts.keep_worst: kept by block on the CPU, by grain on the GPU)
    """
    positions: np.ndarray
    velocities: np.ndarray
    angular_velocities: np.ndarray
    orientations: np.ndarray
    forces: np.ndarray
    torques: np.ndarray
    accelerations: np.ndarray
    angular_accelerations: np.ndarray
    radii: np.ndarray
    masses: np.ndarray
    inertias: np.ndarray
    materials: np.ndarray
    fixed: np.ndarray
    reference_positions: np.ndarray
    max_overlap: np.ndarray


class Pairs(NamedTuple):
    """The neighbour list of grain pairs (i < j listed by one of them) with its contact
    state (Simulation.pairs; core/neighbors.py builds it).

    start : (N + 1,) int64 CSR start of each grain's listed pairs
    partners : (P,) uint32 second grain j of each listed pair
    history : (P, H) float64 contact history (tangential spring [m], ...: the model's)
    scratch_start, scratch_partners, scratch_history : as start, partners, history: the
      next list while a rebuild runs; between rebuilds scratch_partners holds the grain
      that lists each pair (neighbors.list_owners), which the pair walk reads
    reverse_start : (N + 1,) int64, reverse_pairs : (P,) uint32 CSR of the pairs that
      list each grain as their second grain (the gather's reverse list)
    force : (P, 3) float64 [N] force on the first grain of each pair
    own : (N, 6) float64 [N, N m] force and torque summed on each grain by the pair walk
      (rewritten by every evaluation: not in a checkpoint)
    torque_j : (P, 3) float64 [N m] torque on the second grain of each pair
    """
    start: np.ndarray
    partners: np.ndarray
    history: np.ndarray
    scratch_start: np.ndarray
    scratch_partners: np.ndarray
    scratch_history: np.ndarray
    reverse_start: np.ndarray
    reverse_pairs: np.ndarray
    force: np.ndarray
    own: np.ndarray
    torque_j: np.ndarray


class WallPairs(NamedTuple):
    """The grain-wall candidate list with its contact state (Simulation.wall_pairs).

    start : (N + 1,) int64 CSR start of each grain's wall candidates
    ids : (Q,) uint32 wall of each candidate
    history : (Q, H) float64 contact history
    scratch_start, scratch_ids, scratch_history : the next list while a rebuild runs;
      between rebuilds scratch_ids holds the grain of each candidate
      (neighbors.list_owners)
    force : (Q, 3) float64 [N] force of the wall on the grain
    torque : (Q, 3) float64 [N m] torque of the wall on the grain
    """
    start: np.ndarray
    ids: np.ndarray
    history: np.ndarray
    scratch_start: np.ndarray
    scratch_ids: np.ndarray
    scratch_history: np.ndarray
    force: np.ndarray
    torque: np.ndarray


class Images(NamedTuple):
    """The symmetry planes and the list of mirror-image contacts they make, with its
    contact state (Simulation.images; core/symmetry.py builds it and states the
    geometry).

    flag : (3,) int64, 1 along an axis with a symmetry plane;  at : (3,) float64 [m] its
      coordinate
    start : (N + 1,) int64 CSR start of each grain's image candidates
    ids : (I,) uint32 code j * symmetry.MASKS + mask of each candidate: the grain j
      whose image it is and the mirrored axes
    history : (I, H) float64 contact history
    scratch_start, scratch_ids, scratch_history : the next list while a rebuild runs;
      between rebuilds scratch_ids holds the grain of each candidate
    force : (I, 3) float64 [N] force of the image on the grain
    torque : (I, 3) float64 [N m] torque of the image on the grain
    """
    flag: np.ndarray
    at: np.ndarray
    start: np.ndarray
    ids: np.ndarray
    history: np.ndarray
    scratch_start: np.ndarray
    scratch_ids: np.ndarray
    scratch_history: np.ndarray
    force: np.ndarray
    torque: np.ndarray


class WallBundle(NamedTuple):
    """The walls (core/walls.py Walls arrays) and their contact list, as the loop sees
    them (Simulation._walls()).

    kind : (W,) int64 shape id (PLANE, CYLINDER, ...: core/walls.py)
    geometry : (W, G) float64 the shape's row (point [m], unit normal or axis, radius
      [m], ...: core/walls.py; G is read from the array)
    motion_kind : (W,) int64 motion id;  motion : (W, 8) float64 its parameters
    base : (W, 3) float64 [m] reference place of a sinusoid
    offset : (W, 3) float64 [m] displacement from where the wall was built
    velocity : (W, 3) float64 [m/s];  material : (W,) int32 material index
    force : (W, 3) float64 [N] total force of the grains on each wall
    reference_offset : (W, 3) float64 [m] offsets at the last neighbour build
    wall_start .. contact_torque : the WallPairs arrays (WALL_CONTACT_FIELDS maps
      their names): wall_start (N + 1,) int64, wall_ids (Q,) uint32, wall_history
      (Q, H) float64, scratch_wall_start, scratch_wall_ids, scratch_wall_history,
      contact_force (Q, 3) float64 [N], contact_torque (Q, 3) float64 [N m]
    """
    kind: np.ndarray
    geometry: np.ndarray
    motion_kind: np.ndarray
    motion: np.ndarray
    base: np.ndarray
    offset: np.ndarray
    velocity: np.ndarray
    material: np.ndarray
    force: np.ndarray
    reference_offset: np.ndarray
    wall_start: np.ndarray
    wall_ids: np.ndarray
    wall_history: np.ndarray
    scratch_wall_start: np.ndarray
    scratch_wall_ids: np.ndarray
    scratch_wall_history: np.ndarray
    contact_force: np.ndarray
    contact_torque: np.ndarray


# WallPairs field -> its name in WallBundle (the walls' own ``force`` is another array)
WALL_CONTACT_FIELDS = {"start": "wall_start", "ids": "wall_ids", "history": "wall_history",
                       "scratch_start": "scratch_wall_start",
                       "scratch_ids": "scratch_wall_ids",
                       "scratch_history": "scratch_wall_history", "force": "contact_force",
                       "torque": "contact_torque"}
assert tuple(WALL_CONTACT_FIELDS) == WallPairs._fields
# the fields of WallBundle that are one row per wall (the others are the contact list)
WALL_TABLE_FIELDS = tuple(f for f in WallBundle._fields
                          if f not in WALL_CONTACT_FIELDS.values())


def wall_bundle(walls, reference_offset, wall_pairs):
    """The WallBundle of Walls ``walls``, the offsets at the last build and the
    WallPairs ``wall_pairs``."""
    return WallBundle(kind=walls.kind, geometry=walls.geometry, motion_kind=walls.motion_kind,
                      motion=walls.motion, base=walls.base, offset=walls.offset,
                      velocity=walls.velocity, material=walls.material, force=walls.force,
                      reference_offset=reference_offset,
                      **{WALL_CONTACT_FIELDS[k]: v for k, v in wall_pairs._asdict().items()})


class LawWorkspace(NamedTuple):
    """The batched law's scratch for the CPU's contact loops (law_loop.workspace,
    made ready by law_loop.prepare; contacts.contact_forces).

    address : int address of the law loop compiled for the model (law_loop.law_address)
    planar : int address of the 2D pair walk compiled for the model
      (planar.planar_address; 0 for a 3D system)
    work : (B, rows * STRIDE) float64 workspaces, 64-byte aligned (law_loop.py)
    slots : (B, 3, CAP) int64 pair (or wall candidate), first and second grain of each
      workspace column
    dirty : (P,) uint8 1 where a pair slot may hold a non-zero force or history
    sums : (B, 2) float64 [J] energies (normal, tangential) each block dissipated
    collisions : (B, 2) int64 grain-pair and grain-wall contacts that started in each
      block (contacts.touch)
    """
    address: int
    planar: int
    work: np.ndarray
    slots: np.ndarray
    dirty: np.ndarray
    sums: np.ndarray
    collisions: np.ndarray


class LoopArrays(NamedTuple):
    """The loop's own arrays that travel to the GPU (engines/soft/gpu/layout.py).

    clock : (12,) float64, loop.TIME.. slots (one row per system on the device)
    integrator_history : (slots, N, 3) float64 the integrator's per-grain history
    """
    clock: np.ndarray
    integrator_history: np.ndarray
