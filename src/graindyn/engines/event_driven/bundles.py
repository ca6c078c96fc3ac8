"""The bundles of arrays the event loop (events.py) is handed, by name (namedtuples of
arrays: numba compiles them as tuples and reads fields by name).  N grains, W walls,
M materials, C cells; the periodic box is core.walls.PeriodicBox."""
from typing import NamedTuple

import numpy as np


class Grains(NamedTuple):
    """positions, velocities, angular_velocities (N, 3) [m], [m/s], [rad/s], each grain
    at its own time local_time (N,) [s];  orientations (N, 4) unit quaternions, each at
    its grain's last collision or the last pause, whichever is later (events._turn);
    radii, masses, inertias (N,) [m], [kg], [kg m^2];  materials (N,) int32;  fixed (N,)
    int8 (held grains: infinite mass);  collisions (N,) int64, each grain's collision
    counter;  last_collision (N,) [s] the time of its last collision (-inf before any);
    gravity (3,) [m/s^2]."""
    positions: np.ndarray
    velocities: np.ndarray
    angular_velocities: np.ndarray
    orientations: np.ndarray
    radii: np.ndarray
    masses: np.ndarray
    inertias: np.ndarray
    materials: np.ndarray
    fixed: np.ndarray
    local_time: np.ndarray
    collisions: np.ndarray
    last_collision: np.ndarray
    gravity: np.ndarray


class Calendar(NamedTuple):
    """Each grain's next events: next_time (N,) [s], kind (N,) (events.NONE ... RECHECK),
    partner (N,) (grain or wall), count (N,) the partner grain's collision counter when
    predicted, of its next collision;  cross_time (N,) [s] and face (N,) of its next cell
    crossing;  time (N,) [s] the earlier of the two;  heap, key, where, bucket, after,
    before (N,), first (B + 1,), span (2,) [s] and cursor (2,): the queue of the events
    (calendar.py)."""
    time: np.ndarray
    next_time: np.ndarray
    kind: np.ndarray
    partner: np.ndarray
    count: np.ndarray
    cross_time: np.ndarray
    face: np.ndarray
    heap: np.ndarray
    key: np.ndarray
    where: np.ndarray
    bucket: np.ndarray
    after: np.ndarray
    before: np.ndarray
    first: np.ndarray
    span: np.ndarray
    cursor: np.ndarray


class Cells(NamedTuple):
    """The cell grid: lo (3,) [m] its lowest corner, size (3,) [m] the cells' sides,
    count (3,) int64 cells per axis;  cell (N,) each grain's cell (x fastest) and coords
    (N, 3) its place along each axis (kept beside the index, so that no event divides
    integers to find it);  head (C,) the first grain of each cell, next, prev (N,) the
    doubly linked lists (-1: none)."""
    lo: np.ndarray
    size: np.ndarray
    count: np.ndarray
    cell: np.ndarray
    coords: np.ndarray
    head: np.ndarray
    next: np.ndarray
    prev: np.ndarray


class WallBundle(NamedTuple):
    """The arrays of core.walls.Walls the loop reads (kind, geometry, base, motion_kind,
    motion, material; a wall is at base + its displacement, flight.wall_displacement) and
    impulse (W, 3) [N s], the impulse of the grains on each wall since the last pause."""
    kind: np.ndarray
    geometry: np.ndarray
    base: np.ndarray
    motion_kind: np.ndarray
    motion: np.ndarray
    material: np.ndarray
    impulse: np.ndarray


class Tables(NamedTuple):
    """restitution (M, M) [-]: the normal restitution e_n of each pair of materials."""
    restitution: np.ndarray
