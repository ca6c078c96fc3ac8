"""Sample preparation: random insertion of polydisperse grains into a container, or a
loose lattice with random velocities (Perez Sec. 4.1), then settling under gravity until
an equilibrium criterion holds (Karrech et al. Sec. 3: E_c/E_p <= epsilon).
"""
import math
from dataclasses import dataclass

import numpy as np

from .._jit import kernel
from ..analysis.energy import energy_budget, kinetic_holders, settling_ratio
from ..analysis.packing import coordination_number, packing_fraction, void_ratio
from ..core.state import cell_order
from ..core.triggers import EnergyRatioBelow, MaxSpeedBelow


@dataclass(frozen=True)
class BoxRegion:
    """Axis-aligned region [lo, hi] [m] (2 or 3 components)."""

    lo: tuple
    hi: tuple

    def bounds(self, dim):
        lo = np.zeros(3)
        hi = np.zeros(3)
        lo[:dim] = self.lo
        hi[:dim] = self.hi
        if len(self.lo) != dim or len(self.hi) != dim or np.any(hi[:dim] <= lo[:dim]):
            raise ValueError(f"box region needs lo < hi with {dim} components")
        return lo, hi, 0.0

    def volume(self, dim):
        return float(np.prod(np.subtract(self.hi, self.lo)))


@dataclass(frozen=True)
class CylinderRegion:
    """Vertical (z) cylinder of ``radius`` [m] about (cx, cy), between z0 and z1 [m];
    with ``clip_lo`` and ``clip_hi`` (x, y) [m], its part within them (the half or
    quarter that symmetry planes through its axis leave, protocols.Vessel.mirrored)."""

    center: tuple
    radius: float
    z0: float
    z1: float
    clip_lo: tuple | None = None
    clip_hi: tuple | None = None

    def bounds(self, dim):
        if dim != 3 or not self.radius > 0 or not self.z1 > self.z0:
            raise ValueError("cylinder region is 3D and needs radius > 0 and z1 > z0")
        cx, cy = self.center
        lo = np.array([cx - self.radius, cy - self.radius, self.z0])
        hi = np.array([cx + self.radius, cy + self.radius, self.z1])
        if self.clip_lo is not None:
            lo[:2] = np.maximum(lo[:2], self.clip_lo)
            hi[:2] = np.minimum(hi[:2], self.clip_hi)
        return lo, hi, float(self.radius)

    def volume(self, dim):
        lo, hi, _ = self.bounds(dim)
        share = float(np.prod((hi - lo)[:2])) / (2 * self.radius) ** 2
        return share * math.pi * self.radius**2 * (self.z1 - self.z0)


@kernel
def _random_sequential(radii, lo, hi, cyl_radius, center, periodic, dim, seed, attempts):
    """Place grains (largest first) at uniform random non-overlapping positions; returns
    positions and the number placed (< N when the region is too full).  Along an axis
    with ``periodic[d]`` the region's extent is the period: positions are uniform over
    it with no margin at the faces, separations are minimum images and the cell search
    wraps around."""
    np.random.seed(seed)
    n = radii.size
    rmax = radii.max()
    cell = 2.0 * rmax
    length = hi - lo
    counts = np.ones(3, np.int64)
    for d in range(dim):
        counts[d] = max(1, int(length[d] / cell))
    head = -np.ones(counts[0] * counts[1] * counts[2], np.int64)
    nxt = -np.ones(n, np.int64)
    pos = np.zeros((n, 3))
    near = np.zeros((3, 3), np.int64)  # the cells searched along each axis
    n_near = np.ones(3, np.int64)
    for i in range(n):
        r = radii[i]
        placed = False
        for _ in range(attempts):
            x = np.zeros(3)
            ok = True
            for d in range(dim):
                if periodic[d]:
                    x[d] = lo[d] + length[d] * np.random.random()
                    continue
                a = lo[d] + r
                b = hi[d] - r
                if b < a:
                    return pos, i
                x[d] = a + (b - a) * np.random.random()
            if cyl_radius > 0.0:
                dx = x[0] - center[0]
                dy = x[1] - center[1]
                if dx * dx + dy * dy > (cyl_radius - r) ** 2:
                    continue
            c = np.zeros(3, np.int64)
            for d in range(dim):
                c[d] = min(counts[d] - 1, int((x[d] - lo[d]) / cell))
            for d in range(3):
                # with one or two cells along an axis the clamped range holds them all
                if periodic[d] and counts[d] >= 3:
                    n_near[d] = 3
                    for k in range(3):
                        near[d, k] = (c[d] - 1 + k) % counts[d]
                else:
                    first = max(0, c[d] - 1)
                    n_near[d] = min(counts[d], c[d] + 2) - first
                    for k in range(n_near[d]):
                        near[d, k] = first + k
            for kx in range(n_near[0]):
                for ky in range(n_near[1]):
                    for kz in range(n_near[2]):
                        j = head[(near[0, kx] * counts[1] + near[1, ky]) * counts[2]
                                 + near[2, kz]]
                        while j >= 0 and ok:
                            d2 = 0.0
                            for d in range(3):
                                s = x[d] - pos[j, d]
                                if periodic[d]:
                                    s -= length[d] * math.floor(s / length[d] + 0.5)
                                d2 += s * s
                            if d2 < (r + radii[j]) ** 2:
                                ok = False
                            j = nxt[j]
            if ok:
                pos[i] = x
                k = (c[0] * counts[1] + c[1]) * counts[2] + c[2]
                nxt[i] = head[k]
                head[k] = i
                placed = True
                break
        if not placed:
            return pos, i
    return pos, n


def region_center(region, lo, hi):
    """(3,) [m]: the axis of a cylinder region (x, y), else the middle of its bounds
    ``lo``, ``hi``."""
    center = 0.5 * (lo + hi)
    if isinstance(region, CylinderRegion):
        center[:2] = region.center
    return center


def random_insertion(radii, region, rng, dim=3, attempts=20000, periodic=()):
    """Random non-overlapping positions (N, 3) [m] for grains of ``radii`` in ``region``.

    Grains are placed largest first, so the returned order follows the sorted radii:
    returns (positions, radii) both in that order.  ``periodic``: the axes (0..dim-1)
    along which the region (a BoxRegion) spans the period of a periodic box; there the
    positions fill [lo, hi) up to the faces and grains are kept apart across them
    (minimum image), so that no pair overlaps through a periodic face.  Random
    sequential addition jams near a packing fraction of 0.38 (3D) / 0.55 (2D): a
    ValueError says so when the region is too small for the grains.
    """
    radii = np.sort(np.asarray(radii, dtype=np.float64))[::-1].copy()
    lo, hi, cyl = region.bounds(dim)
    flag = np.zeros(3, np.int64)
    for axis in periodic:
        if axis not in range(dim) or cyl > 0:
            raise ValueError(f"periodic = {tuple(periodic)}: periodic axes are among "
                             f"0..{dim - 1} of a box region")
        if hi[axis] - lo[axis] < 2.0 * radii.max(initial=0.0):
            raise ValueError(f"periodic axis {axis}: the period {hi[axis] - lo[axis]:.4g} "
                             f"m is shorter than the largest diameter {2 * radii.max():.4g}"
                             " m (the grain would overlap its own image)")
        flag[axis] = 1
    pos, placed = _random_sequential(radii, lo, hi, cyl, region_center(region, lo, hi), flag,
                                     dim, int(rng.integers(2**31)), attempts)
    if placed < radii.size:
        fraction = float(np.sum(4 / 3 * np.pi * radii**3 if dim == 3 else np.pi * radii**2)
                         / region.volume(dim))
        raise ValueError(f"random insertion placed only {placed} of {radii.size} grains: the "
                         f"region is too small (solid fraction {fraction:.3f} asked); make it "
                         "taller or use a loose lattice")
    return pos, radii


def lattice_insertion(radii, region, rng, dim=3, gap=0.05, speed=0.0):
    """Grains on a simple-cubic (square) lattice of spacing (1 + gap) d_max filling
    ``region`` from the bottom, with random velocities of magnitude ``speed`` [m/s] in
    random directions (Perez Sec. 4.1).  Returns (positions (N, 3), velocities (N, 3))."""
    radii = np.asarray(radii, dtype=np.float64)
    lo, hi, cyl = region.bounds(dim)
    a = 2.0 * radii.max() * (1.0 + gap)
    axes = [np.arange(lo[d] + 0.5 * a, hi[d] - 0.5 * a + 1e-12, a) for d in range(dim - 1)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, dim - 1)
    if cyl > 0:
        c = region_center(region, lo, hi)[: dim - 1]
        grid = grid[np.linalg.norm(grid - c, axis=1) <= cyl - 0.5 * a]
    layers = math.ceil(radii.size / max(1, len(grid)))
    top = lo[dim - 1] + 0.5 * a + (layers - 1) * a
    if len(grid) == 0 or top > hi[dim - 1] - 0.5 * a + 1e-12:
        raise ValueError(f"a lattice of spacing {a:.3g} m holds {len(grid)} grains per layer: "
                         f"{layers} layers do not fit in the region")
    pos = np.zeros((radii.size, 3))
    for k in range(radii.size):
        layer, cell = divmod(k, len(grid))
        pos[k, : dim - 1] = grid[cell]
        pos[k, dim - 1] = lo[dim - 1] + 0.5 * a + layer * a
    v = rng.normal(size=(radii.size, dim))
    v *= speed / np.linalg.norm(v, axis=1, keepdims=True)
    vel = np.zeros((radii.size, 3))
    vel[:, :dim] = v
    return pos, vel


def maxwellian_velocities(masses, temperature, rng, dim=3):
    """Velocities (N, 3) [m/s] of grains of ``masses`` [kg] (N,) drawn from the
    Maxwell-Boltzmann distribution of granular temperature ``temperature`` [J]: each of
    the ``dim`` components of grain i normal with variance T / m_i (z zero in 2D).

    The granular temperature is T = sum_i m_i |v_i|^2 / (dim N) [J], twice the mean
    translational kinetic energy per degree of freedom (E_k = dim N T / 2).  The draw is
    then made exact: the total momentum is removed (the mass-weighted mean velocity
    subtracted, so that the sample does not drift) and the velocities are scaled so
    that T is ``temperature`` exactly (removing the drift takes dim of the dim N degrees
    of freedom; the scaling gives their share of energy back to the others).
    ValueError for a negative or non-finite temperature, for masses that are empty or
    not positive, and for one grain at T > 0 (at rest once its momentum is removed).
    """
    masses = np.asarray(masses, dtype=np.float64)
    if dim not in (2, 3):
        raise ValueError(f"dim = {dim}: 2 or 3")
    if masses.ndim != 1 or masses.size == 0 or not np.all((masses > 0) & (masses < np.inf)):
        raise ValueError("masses: a non-empty 1-D array of positive grain masses [kg]")
    if not (math.isfinite(temperature) and temperature >= 0):
        raise ValueError(f"temperature = {temperature}: the granular temperature [J] "
                         "must be finite and >= 0")
    velocities = np.zeros((masses.size, 3))
    if temperature == 0:
        return velocities
    if masses.size < 2:
        raise ValueError("masses: one grain is at rest once its momentum is removed; a "
                         "temperature > 0 needs two grains or more")
    v = rng.normal(size=(masses.size, dim)) * np.sqrt(temperature / masses)[:, None]
    v -= masses @ v / masses.sum()
    v *= math.sqrt(dim * masses.size * temperature / np.sum(masses[:, None] * v**2))
    velocities[:, :dim] = v
    return velocities


def settle(sim, criterion=None, max_time=5.0, bottom_wall=None, cross_section=None,
           every=()):
    """Run under gravity until ``criterion`` (default EnergyRatioBelow(1e-6)) holds or
    ``max_time`` [s] passes; returns a report of the settled sample.

    Report: reached (bool), time_s, packing_fraction and void_ratio of the bed (from the
    container ``cross_section`` area [m^2] (2D: width [m]) between the bottom wall and
    the top of the highest grain; ``_core`` leaves out two diameters at each end, where
    the walls and the free surface loosen the packing), coordination numbers, the apparent weight on
    ``bottom_wall`` (a wall name) against the total weight (instantaneous: it still
    rings with the bed's elastic oscillations), and the energy budget [J].
    """
    criterion = criterion or EnergyRatioBelow(1e-6)
    if not isinstance(criterion, (EnergyRatioBelow, MaxSpeedBelow)):
        raise TypeError("criterion must be EnergyRatioBelow or MaxSpeedBelow")
    status = sim.run(time=max_time, until=criterion, every=every)
    return settle_report(sim, status == "condition", criterion, bottom_wall, cross_section)


def settle_report(sim, reached, criterion, bottom_wall=None, cross_section=None):
    """The report of ``settle`` for a sample whose settling run has ended; with it the
    criterion's E_kin/E_pot (``energy_ratio``), the rotational share of E_kin and, when
    the criterion was not met, the grains that hold most of E_kin
    (analysis.energy.kinetic_holders)."""
    s = sim.state
    up = 2 if s.dim == 3 else 1
    energy = energy_budget(sim)
    kinetic = energy["kinetic"] + energy["rotational"]
    report = {"reached": bool(reached), "criterion": repr(criterion), "grains": s.n,
              "time_s": sim.time, "steps": sim.step,
              "coordination_number": coordination_number(sim),
              "coordination_number_mechanical": coordination_number(sim, exclude_rattlers=True),
              "energy_J": energy, "energy_ratio": settling_ratio(s, sim.gravity),
              "rotational_share": energy["rotational"] / kinetic if kinetic > 0 else 0.0}
    if not reached:
        report["kinetic_holders"] = kinetic_holders(sim)
    weight = float(np.sum(s.masses[s.fixed == 0]) * np.linalg.norm(sim.gravity))
    report["total_weight_N"] = weight
    if bottom_wall is not None:
        k = sim.walls.index(bottom_wall)
        report["apparent_weight_N"] = sim.walls.normal_force(k)
        report["apparent_weight_ratio"] = report["apparent_weight_N"] / weight
        base = float(sim.walls.geometry[k, up] + sim.walls.offset[k, up])
    else:
        base = float(np.min(s.positions[:, up] - s.radii))
    top = float(np.max(s.positions[:, up] + s.radii))
    report["bed_height_m"] = top - base
    if cross_section is not None:
        phi = packing_fraction(s, cross_section, base, top)
        report["packing_fraction"] = phi
        report["void_ratio"] = void_ratio(phi)
        d = 2.0 * float(s.radii.mean())
        if top - base > 6 * d:
            core = packing_fraction(s, cross_section, base + 2 * d, top - 2 * d)
            report["packing_fraction_core"] = core
            report["void_ratio_core"] = void_ratio(core)
    return report


def fill(vessel, radii, rng, insertion="random", packing_fraction=0.2, lattice_gap=0.05,
         lattice_speed=0.0, periodic=()):
    """Grains of ``radii`` [m] put into ``vessel`` (protocols.base.Vessel) from its
    floor: "random" non-overlapping positions in a region of solid fraction
    ``packing_fraction`` (None: the whole vessel, which must be closed), in cell order (touching grains at nearby indices), or a loose
    "lattice" of gap ``lattice_gap`` (fraction of d_max) with random velocities of
    ``lattice_speed`` [m/s].  ``periodic``: the periodic directions (axis, lo [m],
    hi [m]) of the box; random insertion treats as periodic each axis whose [lo, hi]
    the region spans exactly, so that no grains overlap through the periodic face (the
    lattice keeps half a spacing from every face, so it needs nothing).  Returns
    (positions (N, 3), radii (N,), velocities (N, 3) or None)."""
    dim = vessel.dim
    if insertion == "random":
        solid = float(np.sum(4 / 3 * np.pi * radii**3 if dim == 3 else np.pi * radii**2))
        height = vessel.top - vessel.floor if packing_fraction is None \
            else solid / (packing_fraction * vessel.cross_section)
        region = vessel.region(height)
        lo, hi, _ = region.bounds(dim)
        axes = [axis for axis, a, b in periodic if lo[axis] == a and hi[axis] == b]
        positions, radii = random_insertion(radii, region, rng, dim, periodic=axes)
        # inserted largest first, at random places: put them cell by cell (cells of
        # about the neighbour cutoff), so that touching grains sit at nearby indices
        order = cell_order(positions, 2.2 * radii.max())
        return positions[order], radii[order], None
    spacing = 2 * radii.max() * (1 + lattice_gap)
    per_layer = max(1.0, (vessel.cross_section / spacing ** (dim - 1)) * 0.7)
    height = (math.ceil(radii.size / per_layer) + 2) * spacing
    positions, velocities = lattice_insertion(radii, vessel.region(height), rng, dim,
                                              lattice_gap, lattice_speed)
    return positions, radii, velocities
