"""Symmetry planes: axis-aligned mirror boundaries, and the list of the mirror-image
contacts they make.

A symmetry plane x_d = c (axis d) stands for the mirror half of a symmetric system
(Karrech et al.'s quarter model of a cylinder, with u_x = 0 on x = 0 and u_y = 0 on
y = 0): every grain j near it has a mirror image j' with

    r_j' = M r_j + (I - M) c,   v_j' = M v_j,   w_j' = det(M) M w_j,

M the diagonal reflection (-1 on the mirrored axes, +1 on the others) and c the planes'
coordinates; angular velocity is a pseudovector, hence det(M).  With planes along two
(three) axes a grain near their edge (corner) has images through each plane and
through both (all), the masks of mirrored axes 1..7 below.  A grain i then touches
the images of the grains near the plane, its own included, with the grain-grain law and
its own contact history, exactly as the grains of the mirror half would touch it in
the full system when the motion is symmetric.  The plane itself exerts no force: a
grain pushed against it meets its own image, which pushes back with the law of two
grains (a grain at distance R_i from the plane touches its image).

What it reproduces, and what not: the full system as long as its motion stays
symmetric about the planes (the mean of a bed, a load that is symmetric); it enforces
the symmetry, so fluctuations that break it (a grain crossing the plane, an
asymmetric buckling of the bed) are not there, and a statistic of the quarter is that
of a full system whose random packing is itself symmetric.

Kernel layout (the symmetry group of bundles.Mirrors): flag (3,) int64, 1 along an
axis with a plane; at (3,) float64 [m] the plane's coordinate.  An image candidate is
listed by the grain i it acts on as the code j * MASKS + mask (uint32) of the grain j
whose image it is and of the mirrored axes (bit d for axis d); i lists (i, j') and j
lists (j, i'), the same contact seen from each side, and (i, i') once.  Listing every
candidate by the grain it acts on keeps each force a write to one grain only.
"""
import math
from dataclasses import dataclass

import numpy as np

from .._jit import inlined, kernel, parallel, prange, scalar
from .neighbors import (carry_history, cell_grid, cell_of, cell_sort, list_owners, min_image,
                        neighbour_cell)

MASKS = 8          # image codes: j * MASKS + mask, mask in 1..7 (bit d: axis d mirrored)
AXES = "xyz"


@dataclass(frozen=True)
class Symmetry:
    """A symmetry plane x_axis = ``at`` [m] (axis 0, 1, 2 or "x", "y", "z"); the grains
    live on the side ``side`` (+1: coordinates above ``at``, -1: below) of it."""

    axis: int | str
    at: float = 0.0
    side: int = 1

    @property
    def index(self):
        """The axis as 0, 1 or 2."""
        if isinstance(self.axis, str):
            if self.axis not in AXES:
                raise ValueError(f"symmetry plane axis must be x, y, z or 0..2, got "
                                 f"{self.axis!r}")
            return AXES.index(self.axis)
        return int(self.axis)


class SymmetryPlanes:
    """The symmetry planes of a simulation: at most one per axis, none along a periodic
    axis, along the first ``dim`` axes only.  ``flag`` and ``at`` are the kernel arrays
    (module docstring)."""

    def __init__(self, planes=(), dim=3, periodic_flag=(0, 0, 0)):
        self.planes = list(planes)
        self.flag = np.zeros(3, np.int64)
        self.at = np.zeros(3)
        self.side = np.ones(3)
        for p in self.planes:
            d = p.index
            if d not in range(dim):
                raise ValueError(f"symmetry plane along axis {p.axis!r}: a {dim}D system has "
                                 f"axes 0..{dim - 1}")
            if not math.isfinite(p.at) or p.side not in (1, -1):
                raise ValueError(f"symmetry plane {p}: needs a finite coordinate [m] and "
                                 "side +1 or -1")
            if self.flag[d]:
                raise ValueError(f"two symmetry planes along axis {AXES[d]}: at most one per "
                                 "axis (two parallel mirrors make an infinite system)")
            if periodic_flag[d]:
                raise ValueError(f"axis {AXES[d]} is periodic: it cannot have a symmetry "
                                 "plane too")
            self.flag[d] = 1
            self.at[d] = float(p.at)
            self.side[d] = p.side

    def __bool__(self):
        return bool(self.flag.any())

    def __len__(self):
        return len(self.planes)

    def masks(self):
        """The image masks these planes make: every non-empty subset of their axes."""
        axes = sum(1 << d for d in range(3) if self.flag[d])
        return [m for m in range(1, MASKS) if m & axes == m]

    def image(self, points, masks):
        """Mirror images (K, 3) [m] of ``points`` (K, 3) through the planes of ``masks``
        (K,) (the NumPy twin of ``mirror``)."""
        points = np.array(points, dtype=np.float64)
        masks = np.broadcast_to(np.asarray(masks), points.shape[:1])
        for d in range(3):
            hit = (masks >> d) & 1 == 1
            points[hit, d] = 2.0 * self.at[d] - points[hit, d]
        return points

    def inside(self, points, radii=None):
        """(K,) bool: the points on the grains' side of every plane (by more than their
        radius when ``radii`` is given)."""
        points = np.asarray(points, dtype=np.float64)
        margin = 0.0 if radii is None else np.asarray(radii)
        ok = np.ones(points.shape[0], bool)
        for d in range(3):
            if self.flag[d]:
                ok &= self.side[d] * (points[:, d] - self.at[d]) >= margin
        return ok


@scalar
def mirror(x, d, mask, at):
    """Coordinate ``x`` along axis d of the image through the planes of ``mask``."""
    if (mask >> d) & 1:
        return 2.0 * at[d] - x
    return x


@scalar
def mirror_sign(d, mask):
    """-1.0 along an axis the image of ``mask`` mirrors, else 1.0 (the diagonal of M)."""
    return -1.0 if (mask >> d) & 1 else 1.0


@scalar
def spin_sign(d, mask):
    """The diagonal of det(M) M, which maps an angular velocity to its image's."""
    det = mirror_sign(0, mask) * mirror_sign(1, mask) * mirror_sign(2, mask)
    return det * mirror_sign(d, mask)


@scalar
def image_separation(i, code, positions, at, periodic_flag, periodic_length):
    """r_i - r_j' [m] (3) of image candidate ``code`` of grain i (module docstring)."""
    j = code // MASKS
    mask = code % MASKS
    return (min_image(positions[i, 0] - mirror(positions[j, 0], 0, mask, at),
                      periodic_flag[0], periodic_length[0]),
            min_image(positions[i, 1] - mirror(positions[j, 1], 1, mask, at),
                      periodic_flag[1], periodic_length[1]),
            min_image(positions[i, 2] - mirror(positions[j, 2], 2, mask, at),
                      periodic_flag[2], periodic_length[2]))


@inlined
def image_row(i, positions, radii, r_max, skin, flag, at, cell, origin, size, counts,
              cell_start, cell_items, periodic_flag, periodic_length, write, out, base):
    """Count the image candidates of grain i (|r_i - r_j'| < R_i + R_j + skin), writing
    their codes at out[base:] when ``write``; masks in increasing order, then cells and
    grain index as the pair search (neighbors.scan_grain)."""
    k = 0
    for mask in range(1, MASKS):
        usable = True
        for d in range(3):
            if (mask >> d) & 1 and (flag[d] == 0 or abs(positions[i, d] - at[d])
                                    >= radii[i] + r_max + skin):
                usable = False
        if not usable:
            continue
        # the cells around the image of i hold the grains whose images are near i
        px = mirror(positions[i, 0], 0, mask, at)
        py = mirror(positions[i, 1], 1, mask, at)
        pz = mirror(positions[i, 2], 2, mask, at)
        cx = cell_of(px, origin[0], size[0], counts[0])
        cy = cell_of(py, origin[1], size[1], counts[1])
        cz = cell_of(pz, origin[2], size[2], counts[2])
        for ox in range(3):
            ax = neighbour_cell(cx, ox, counts[0], periodic_flag[0])
            if ax < 0:
                continue
            for oy in range(3):
                ay = neighbour_cell(cy, oy, counts[1], periodic_flag[1])
                if ay < 0:
                    continue
                for oz in range(3):
                    az = neighbour_cell(cz, oz, counts[2], periodic_flag[2])
                    if az < 0:
                        continue
                    cc = (ax * counts[1] + ay) * counts[2] + az
                    for s in range(cell_start[cc], cell_start[cc + 1]):
                        j = cell_items[s]
                        code = j * MASKS + mask
                        dx, dy, dz = image_separation(i, code, positions, at, periodic_flag,
                                                      periodic_length)
                        cut = radii[i] + radii[j] + skin
                        if dx * dx + dy * dy + dz * dz < cut * cut:
                            if write:
                                out[base + k] = code
                            k += 1
    return k


@parallel
def _image_candidates(positions, radii, r_max, skin, flag, at, cell, origin, size, counts,
                      cell_start, cell_items, periodic_flag, periodic_length, start, codes,
                      write):
    """Count (write=False: start becomes the CSR, returns the total) or list the image
    candidates of every grain."""
    n = positions.shape[0]
    for i in prange(n):
        k = image_row(np.int64(i), positions, radii, r_max, skin, flag, at, cell, origin,
                      size, counts, cell_start, cell_items, periodic_flag, periodic_length,
                      write, codes, start[i])
        if not write:
            start[i + 1] = k
    if not write:
        start[0] = 0
        for i in range(n):
            start[i + 1] += start[i]
    return start[n]


@kernel
def rebuild_images(positions, radii, skin, periodic_flag, periodic_lo, periodic_length, flag,
                   at, start, codes, history, scratch_start, scratch_codes, scratch_history):
    """Rebuild the image-candidate list in place at the current positions, carrying the
    history of the candidates that stay over (neighbors.carry_history).  Returns
    the candidates needed; when that exceeds the capacity nothing has changed and the
    caller must grow the arrays.  scratch_codes then holds the grain of each candidate
    (neighbors.list_owners)."""
    n = positions.shape[0]
    r_max = radii.max()
    origin, size, counts = cell_grid(positions, 2.0 * r_max + skin, periodic_flag, periodic_lo,
                                     periodic_length)
    cell_start, cell_items, cell = cell_sort(positions, origin, size, counts)
    needed = _image_candidates(positions, radii, r_max, skin, flag, at, cell, origin, size,
                               counts, cell_start, cell_items, periodic_flag, periodic_length,
                               scratch_start, scratch_codes, np.bool_(False))
    if needed > codes.size:
        return needed
    _image_candidates(positions, radii, r_max, skin, flag, at, cell, origin, size, counts,
                      cell_start, cell_items, periodic_flag, periodic_length, scratch_start,
                      scratch_codes, np.bool_(True))
    carry_history(start, codes, history, scratch_start, scratch_codes, scratch_history)
    start[:] = scratch_start
    codes[:needed] = scratch_codes[:needed]
    history[:needed] = scratch_history[:needed]
    list_owners(start, n, scratch_codes)
    return needed
