"""The bundles of arrays the contact dynamics loop (stepping.advance) is handed, by
name (namedtuples of arrays: numba compiles them as tuples and reads fields by name).
Shapes: N grains, W walls, M materials, P pair slots, Q wall-candidate slots (the lists'
capacities, detection.Lists)."""
from typing import NamedTuple

import numpy as np


class Grains(NamedTuple):
    """positions, velocities, angular_velocities : (N, 3) [m], [m/s], [rad/s]
    orientations : (N, 4) unit quaternions;  radii, masses, inertias : (N,) [m], [kg],
    [kg m^2];  inv_mass, inv_inertia : (N,) [1/kg], [1/(kg m^2)], zero for held grains
    materials : (N,) int32;  fixed : (N,) int8
    reference_positions : (N, 3) [m] at the last list build
    old_velocities, old_angular_velocities : (N, 3) the velocities at the step's start"""
    positions: np.ndarray
    velocities: np.ndarray
    angular_velocities: np.ndarray
    orientations: np.ndarray
    radii: np.ndarray
    masses: np.ndarray
    inertias: np.ndarray
    inv_mass: np.ndarray
    inv_inertia: np.ndarray
    materials: np.ndarray
    fixed: np.ndarray
    reference_positions: np.ndarray
    old_velocities: np.ndarray
    old_angular_velocities: np.ndarray


class WallBundle(NamedTuple):
    """The arrays of core.walls.Walls (kind, geometry, offset, base, velocity, force,
    motion_kind, motion, material) and reference_offset (W, 3) [m], the offsets at the
    last list build; solved (W, 10) and push (W,) [N s], the rows of the servo walls and
    pistons of the step's solve (solver.solved_velocity), rewritten every step."""
    kind: np.ndarray
    geometry: np.ndarray
    offset: np.ndarray
    base: np.ndarray
    velocity: np.ndarray
    force: np.ndarray
    motion_kind: np.ndarray
    motion: np.ndarray
    material: np.ndarray
    reference_offset: np.ndarray
    solved: np.ndarray
    push: np.ndarray


class Tables(NamedTuple):
    """Per pair of materials (grain or wall): restitution (M, M) [-] (Newton's e_n),
    friction (M, M, 2) [-] (mu_s, mu_d), rolling (M, M) [-] (mu_r)."""
    restitution: np.ndarray
    friction: np.ndarray
    rolling: np.ndarray


class Work(NamedTuple):
    """The solver's per-contact work space: active (P,), wall_active (Q,) bool (gap below
    the detection gap this step); bound (P,), wall_bound (Q,) [m/s] the normal velocity
    bounds; free (P, 6), wall_free (Q, 6) the free relative velocities of the contact
    points [m/s] (0-2) and the free relative spins [rad/s] (3-5)."""
    active: np.ndarray
    wall_active: np.ndarray
    bound: np.ndarray
    wall_bound: np.ndarray
    free: np.ndarray
    wall_free: np.ndarray


def new_work(pairs, wall_candidates):
    """Work space for ``pairs`` pair slots and ``wall_candidates`` wall slots."""
    return Work(np.zeros(pairs, np.bool_), np.zeros(wall_candidates, np.bool_),
                np.zeros(pairs), np.zeros(wall_candidates), np.zeros((pairs, 6)),
                np.zeros((wall_candidates, 6)))
