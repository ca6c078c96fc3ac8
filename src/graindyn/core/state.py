"""State: the grains as a struct of float64 arrays, in 2D (disks) or 3D (spheres).

Both dimensions use 3-component vectors so one compiled kernel serves both: in 2D the
z components of positions and velocities and the x, y components of angular
velocities stay zero, the orientation is a rotation about z (``angles`` gives it) and
``density`` is an areal density [kg/m^2].
"""
from dataclasses import dataclass, field

import numpy as np


def sample_radii(n, distribution, rng, *, d_min=None, d_max=None, mean=None, std=None):
    """Radii [m] of n grains from a diameter distribution.

    distribution: "uniform" (diameters uniform in [d_min, d_max], as in Oquendo and
    Perez), "normal" (mean, std of the diameter, truncated to [d_min, d_max] when
    given) or "lognormal" (mean and std of the diameter itself, not of its log).
    """
    if n < 1:
        raise ValueError(f"number of grains must be >= 1, got {n}")
    if distribution == "uniform":
        if d_min is None or d_max is None or not 0 < d_min <= d_max:
            raise ValueError(f"uniform diameters need 0 < d_min <= d_max, got {d_min}, {d_max}")
        d = rng.uniform(d_min, d_max, n) if d_max > d_min else np.full(n, float(d_min))
    elif distribution in ("normal", "lognormal"):
        if mean is None or std is None or mean <= 0 or std < 0:
            raise ValueError(f"{distribution} diameters need mean > 0 and std >= 0")
        lo = d_min if d_min is not None else 1e-6 * mean
        hi = d_max if d_max is not None else np.inf
        if distribution == "normal":
            draw = lambda k: rng.normal(mean, std, k)
        else:
            s2 = np.log1p((std / mean) ** 2)
            draw = lambda k: rng.lognormal(np.log(mean) - 0.5 * s2, np.sqrt(s2), k)
        d = np.empty(0)
        for _ in range(1000):
            x = draw(n)
            d = np.concatenate([d, x[(x >= lo) & (x <= hi)]])
            if d.size >= n:
                break
        else:
            raise ValueError("diameter bounds reject almost every draw of the distribution")
        d = d[:n]
    else:
        raise ValueError(f"unknown diameter distribution {distribution!r}; "
                         "choose uniform, normal or lognormal")
    return 0.5 * d


def cell_order(positions, cell):
    """The order that puts grains cell by cell: cubic cells of side ``cell`` [m] counted
    from the lowest corner of the grains, x fastest, then y, then z, the grains of a
    cell in their present order (LAMMPS sorts its atoms the same way, `atom_modify
    sort`).  Grains that touch then sit at nearby indices, and the contact loops find
    their data in cache: a 1e5-grain bed given in lattice order ran 500 steps about 20 %
    faster in cells of the neighbour cutoff (measured with benchmarks/lammps_bed.py --file-order).  Returns the
    permutation for State.reordered."""
    if not cell > 0.0:
        raise ValueError(f"cell must be a positive length, got {cell}")
    p = np.asarray(positions, dtype=np.float64)
    c = np.floor((p - p.min(axis=0)) / cell).astype(np.int64)
    counts = c.max(axis=0) + 1
    code = (c[:, 2] * counts[1] + c[:, 1]) * counts[0] + c[:, 0]
    return np.argsort(code, kind="stable")


@dataclass
class State:
    """N grains: kinematics, shape and material, as contiguous arrays (SI units).

    positions, velocities : (N, 3) [m], [m/s]
    angular_velocities : (N, 3) [rad/s];  orientations : (N, 4) unit quaternions (w, x, y, z)
    forces, torques : (N, 3) [N], [N m] of the last force evaluation
    accelerations, angular_accelerations : (N, 3) integrator history [m/s^2], [rad/s^2]
    radii, masses, inertias : (N,) [m], [kg], [kg m^2];  materials : (N,) int32
    fixed : (N,) int8, 1 for grains the integrator leaves in place
    """

    dim: int
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
    time: float = 0.0
    step: int = 0
    extra: dict = field(default_factory=dict)

    @classmethod
    def create(cls, positions, radii, densities, dim=3, materials=None, velocities=None):
        """Grains at ``positions`` [m] with ``radii`` [m]; ``densities`` per grain or scalar.

        3D: m = 4/3 pi rho R^3, I = 2/5 m R^2 (solid spheres).
        2D: rho is areal [kg/m^2], m = pi rho R^2, I = m R^2/2 (solid disks).
        """
        if dim not in (2, 3):
            raise ValueError(f"dim must be 2 or 3, got {dim}")
        # copies: the State owns its arrays (never the caller's, never a read-only view
        # such as np.broadcast_to's, which the compiled loop would be compiled again for)
        radii = np.array(radii, dtype=np.float64).reshape(-1)
        n = radii.size
        pos = np.zeros((n, 3))
        p = np.asarray(positions, dtype=np.float64).reshape(n, -1)
        if p.shape[1] not in (2, 3) or (dim == 3 and p.shape[1] != 3):
            raise ValueError(f"positions must be (N, {dim}), got {p.shape}")
        pos[:, : p.shape[1]] = p
        if dim == 2:
            pos[:, 2] = 0.0
        if np.any(radii <= 0) or not np.all(np.isfinite(pos)):
            raise ValueError("radii must be positive and positions finite")
        rho = np.broadcast_to(np.asarray(densities, dtype=np.float64), (n,))
        if np.any(rho <= 0):
            raise ValueError("densities must be positive")
        if dim == 3:
            masses = 4.0 / 3.0 * np.pi * rho * radii**3
            inertias = 0.4 * masses * radii**2
        else:
            masses = np.pi * rho * radii**2
            inertias = 0.5 * masses * radii**2
        zeros = lambda: np.zeros((n, 3))
        quat = np.zeros((n, 4))
        quat[:, 0] = 1.0
        state = cls(dim, pos, zeros(), zeros(), quat, zeros(), zeros(), zeros(), zeros(),
                    radii, masses, inertias,
                    np.zeros(n, np.int32) if materials is None
                    else np.array(materials, dtype=np.int32).reshape(-1),
                    np.zeros(n, np.int8))
        if velocities is not None:
            v = np.asarray(velocities, dtype=np.float64).reshape(n, -1)
            state.velocities[:, : v.shape[1]] = v
            if dim == 2:
                state.velocities[:, 2] = 0.0
        return state

    def reordered(self, order) -> "State":
        """A new state whose grain k is grain order[k] of this one (every per-grain array
        permuted alike; time, step and extra kept), e.g. ``order = cell_order(...)``."""
        order = np.asarray(order)
        if order.shape != (self.n,) or not np.array_equal(np.sort(order), np.arange(self.n)):
            raise ValueError("order must be a permutation of the grain indices")
        arrays = {k: np.ascontiguousarray(v[order]) for k, v in self.arrays().items()}
        return State(self.dim, time=self.time, step=self.step, extra=dict(self.extra),
                     **arrays)

    @property
    def n(self) -> int:
        """Number of grains."""
        return self.radii.size

    @property
    def angles(self) -> np.ndarray:
        """2D orientation angle about z [rad], from the quaternion."""
        q = self.orientations
        return 2.0 * np.arctan2(q[:, 3], q[:, 0])

    @property
    def volumes(self) -> np.ndarray:
        """Grain volumes [m^3] (3D) or areas [m^2] (2D)."""
        r = self.radii
        return 4.0 / 3.0 * np.pi * r**3 if self.dim == 3 else np.pi * r**2

    def move(self, indices, positions, velocities, angular_velocities=None) -> np.ndarray:
        """Put grains ``indices`` at ``positions`` (K, 3) [m] with ``velocities`` (K, 3)
        [m/s] and ``angular_velocities`` (K, 3) [rad/s] (None: zero), after checking
        them (distinct indices, finite values, in 2D zero z and zero x, y spins): the
        grains' side of every engine's relocate.  Returns the indices (K,) int64;
        ValueError naming what does not fit."""
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size == 0:
            return idx
        if idx.min() < 0 or idx.max() >= self.n or np.unique(idx).size != idx.size:
            raise ValueError(f"relocate needs distinct grain indices in 0..{self.n - 1}")
        moved = {"positions": positions, "velocities": velocities,
                 "angular_velocities": np.zeros((idx.size, 3)) if angular_velocities is None
                 else angular_velocities}
        for name, value in moved.items():
            value = np.asarray(value, dtype=np.float64)
            if value.shape != (idx.size, 3) or not np.all(np.isfinite(value)):
                raise ValueError(f"relocate: {name} must be finite, ({idx.size}, 3)")
            moved[name] = value
        if self.dim == 2 and (np.any(moved["positions"][:, 2] != 0)
                              or np.any(moved["velocities"][:, 2] != 0)
                              or np.any(moved["angular_velocities"][:, :2] != 0)):
            raise ValueError("relocate in 2D: positions and velocities need zero z "
                             "components, angular velocities zero x and y")
        for name, value in moved.items():
            getattr(self, name)[idx] = value
        return idx

    def kick(self, indices, delta_v) -> np.ndarray:
        """Add ``delta_v`` ((3,) or (K, 3) [m/s]) to the velocities of grains ``indices``,
        leaving their places and spins: the grains' side of every engine's kick.
        Returns the indices (K,) int64; ValueError naming what does not fit."""
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size == 0:
            return idx
        if idx.min() < 0 or idx.max() >= self.n or np.unique(idx).size != idx.size:
            raise ValueError(f"kick needs distinct grain indices in 0..{self.n - 1}")
        dv = np.broadcast_to(np.asarray(delta_v, dtype=np.float64), (idx.size, 3))
        if not np.all(np.isfinite(dv)) or (self.dim == 2 and np.any(dv[:, 2] != 0)):
            raise ValueError("kick: delta_v must be finite, (3,) or (K, 3), with zero z in 2D")
        self.velocities[idx] += dv
        return idx

    def stop(self, indices) -> np.ndarray:
        """Fix grains ``indices`` where they are, at rest (every engine's hold); returns
        the indices (K,) int64, ValueError when one is out of range."""
        idx = np.asarray(indices, dtype=np.int64).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= self.n):
            raise ValueError(f"hold needs grain indices in 0..{self.n - 1}")
        self.fixed[idx] = 1
        self.velocities[idx] = 0.0
        self.angular_velocities[idx] = 0.0
        return idx

    def arrays(self) -> dict:
        """All per-grain arrays by name (for checkpoints and device transfer)."""
        names = ("positions", "velocities", "angular_velocities", "orientations", "forces",
                 "torques", "accelerations", "angular_accelerations", "radii", "masses",
                 "inertias", "materials", "fixed")
        return {k: getattr(self, k) for k in names}
