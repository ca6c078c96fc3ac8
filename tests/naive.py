"""O(N^2) NumPy twins of the engine's neighbour search and force gather (STYLE.md,
"Naive twins").  Slow, obvious and independent of graindyn: every pair is looked at.

Periodic directions are given as ``lengths``: a (3,) array with the box length [m]
along each periodic axis and 0 along the others (minimum image along periodic axes).
The floating-point recipe of the cut-off test (minimum image, r^2 summed x, y, z,
cut = R_i + R_j + skin, r^2 < cut^2) is the textbook one, so that a pair exactly at
the cut-off is judged the same way by both.
"""
import numpy as np


def _lengths(lengths):
    return np.zeros(3) if lengths is None else np.asarray(lengths, dtype=np.float64)


def min_image(d, lengths=None):
    """Minimum-image separations d (..., 3) [m] along the periodic axes."""
    d = np.array(d, dtype=np.float64, copy=True)
    lengths = _lengths(lengths)
    for ax in range(3):
        if lengths[ax] > 0:
            d[..., ax] -= lengths[ax] * np.floor(d[..., ax] / lengths[ax] + 0.5)
    return d


def _upper(n):
    return np.triu_indices(n, k=1)


def separations(positions, lengths=None):
    """(i, j, d, r2) for every pair i < j: d = r_i - r_j (minimum image), r2 = |d|^2."""
    positions = np.asarray(positions, dtype=np.float64)
    i, j = _upper(positions.shape[0])
    d = min_image(positions[i] - positions[j], lengths)
    r2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    return i, j, d, r2


def pairs_within(positions, radii, skin, lengths=None):
    """Set of pairs (i, j), i < j, with |r_i - r_j| < R_i + R_j + skin."""
    radii = np.asarray(radii, dtype=np.float64)
    i, j, _, r2 = separations(positions, lengths)
    cut = radii[i] + radii[j] + skin
    keep = r2 < cut * cut
    return set(zip(i[keep].tolist(), j[keep].tolist()))


def touching_pairs(positions, radii, lengths=None):
    """Set of pairs (i, j), i < j, that overlap: |r_i - r_j| < R_i + R_j."""
    return pairs_within(positions, radii, 0.0, lengths)


def hooke_forces(positions, radii, masses, kn, gravity, lengths=None):
    """Force on each grain [N] from f = kn h n over every overlapping pair (no damping,
    no friction) plus m g, and a per-grain scale (sum of |pair force| + |m g|) [N] for
    round-off tolerances."""
    positions = np.asarray(positions, dtype=np.float64)
    radii = np.asarray(radii, dtype=np.float64)
    masses = np.asarray(masses, dtype=np.float64)
    n = positions.shape[0]
    forces = masses[:, None] * np.asarray(gravity, dtype=np.float64)[None, :]
    scale = np.abs(forces).sum(axis=1)
    i, j, d, r2 = separations(positions, lengths)
    rsum = radii[i] + radii[j]
    on = r2 < rsum * rsum
    i, j, d = i[on], j[on], d[on]
    dist = np.sqrt(r2[on])
    f = (kn * (rsum[on] - dist) / dist)[:, None] * d          # on i, along r_i - r_j
    for a in range(3):
        forces[:, a] += np.bincount(i, f[:, a], minlength=n) - np.bincount(j, f[:, a],
                                                                           minlength=n)
    mag = np.linalg.norm(f, axis=1)
    scale += np.bincount(i, mag, minlength=n) + np.bincount(j, mag, minlength=n)
    return forces, scale


def hertz_energy(positions, radii, youngs_eff, lengths=None):
    """Elastic energy [J] of every overlapping pair: 8/15 E* sqrt(R*) h^(5/2)."""
    radii = np.asarray(radii, dtype=np.float64)
    i, j, _, r2 = separations(positions, lengths)
    rsum = radii[i] + radii[j]
    on = r2 < rsum * rsum
    h = rsum[on] - np.sqrt(r2[on])
    r_eff = radii[i][on] * radii[j][on] / rsum[on]
    return float(np.sum(8.0 / 15.0 * youngs_eff * np.sqrt(r_eff) * h**2.5))


def kinetic_energy(masses, inertias, velocities, angular_velocities):
    """Translational plus rotational kinetic energy [J]."""
    return float(0.5 * np.sum(masses * np.sum(velocities**2, axis=1))
                 + 0.5 * np.sum(inertias * np.sum(angular_velocities**2, axis=1)))


def linear_momentum(masses, velocities):
    """Total linear momentum (3,) [kg m/s] and its scale sum m |v|."""
    p = masses[:, None] * velocities
    return p.sum(axis=0), float(np.linalg.norm(p, axis=1).sum())


def angular_momentum(masses, inertias, positions, velocities, angular_velocities):
    """Total angular momentum about the origin, sum m r x v + I w (3,) [kg m^2/s] (spheres
    and disks: isotropic inertia), and its scale sum m |r| |v| + I |w|."""
    orbital = masses[:, None] * np.cross(positions, velocities)
    spin = inertias[:, None] * angular_velocities
    scale = float(np.sum(masses * np.linalg.norm(positions, axis=1)
                         * np.linalg.norm(velocities, axis=1))
                  + np.sum(inertias * np.linalg.norm(angular_velocities, axis=1)))
    return orbital.sum(axis=0) + spin.sum(axis=0), scale
