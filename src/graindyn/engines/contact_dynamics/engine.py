"""ContactDynamics: rigid spheres (3D) or disks (2D) moved by the Moreau-Jean time
stepping (stepping.py) with contact impulses from the NLGS (solver.py), behind the
engine interface of core/engine.py.

>>> engine = ContactDynamics(state, [Material(restitution=0.5, friction_static=0.4,
...                          friction_sliding=0.4)], walls=box((0, 0, 0), (L, L, H)),
...                          dt=1e-4)                                    # doctest: +SKIP
>>> engine.run(time=0.5); engine.last_iterations, engine.last_residual  # doctest: +SKIP
"""
import math
import warnings

import numpy as np

from ...core.engine import (Contacts, SimulationError, WallContacts, checked_gravity,
                            copy_into)
from ...core.species import Material
from ...core.walls import Walls
from ...core.triggers import NO_CONDITION, pauses
from ..rigid import CONDITION, NAN, RigidGrains
from . import stepping as st
from .bundles import Grains, Tables, WallBundle, new_work
from .detection import new_lists

# rewritten every step before they are read: not part of a snapshot
_TRANSIENT = ("gap", "normal", "wall_gap", "wall_normal", "reverse_start", "reverse_pairs")


def suggested_time_step(state, gravity):
    """The time-step report of rigid grains: the free-fall time over the smallest radius
    sqrt(R_min / |g|) [s] as the time scale of their motion, a step of 1/100 of it
    suggested, at most 1/10 of it advised (a grain then falls well under the detection
    gap per step); dict of criterion, critical_time_s, fraction (None), max_fraction,
    suggested_dt_s.  ValueError without gravity (give dt)."""
    g = float(np.linalg.norm(gravity))
    if not g > 0:
        raise ValueError("without gravity the contact dynamics engine has no time scale: "
                         "give engine.dt")
    t = math.sqrt(float(state.radii.min()) / g)
    return {"criterion": "free-fall time over the smallest radius", "critical_time_s": t,
            "fraction": None, "max_fraction": 0.1, "suggested_dt_s": 0.01 * t}


def material_tables(materials):
    """stepping Tables of the materials, mixed pair by pair by the geometric mean as
    core/species.py does: restitution e (None: 1, elastic), friction (mu_s, mu_d),
    rolling friction mu_r (friction_rolling)."""
    k = len(materials)
    e = np.array([1.0 if m.restitution is None else m.restitution for m in materials])
    mu = np.array([[m.friction_static, m.friction_sliding] for m in materials])
    mu_r = np.array([m.friction_rolling for m in materials])
    for m in materials:
        if m.friction_sliding > m.friction_static:
            raise ValueError(f"material {m.name!r}: friction_sliding {m.friction_sliding} "
                             f"exceeds friction_static {m.friction_static}")
    return Tables(restitution=np.sqrt(np.outer(e, e)).reshape(k, k),
                  friction=np.sqrt(mu[:, None, :] * mu[None, :, :]),
                  rolling=np.sqrt(np.outer(mu_r, mu_r)).reshape(k, k))


class ContactDynamics(RigidGrains):
    """Rigid grains by contact dynamics (Moreau, Jean; Pérez Sec. 2 Eq. 11-12), SI units.

    state : core.state.State;  materials : list of core.species.Material (restitution
      e_n, None = 1; friction_static mu_s, friction_sliding mu_d <= mu_s; friction_rolling
      mu_r, rolling resistance (solver.py); the rest unused)
    walls : Plane/Cylinder/Segment/Disk list (fixed, "velocity", "sinusoid", "servo" or
      "piston" motion; the servo's and the piston's velocity solved with the contacts);
      periodic : Periodic list
    gravity (3,) [m/s^2];  dt [s] (None: suggested_time_step);  theta [-] in [0.5, 1]
      (stepping.py; 1 gives Pérez Eq. 11-12, 0.5 the default: exact free flight)
    gap [m]: contacts are solved when closer than this at a step's start (None: 0.1 of
      the smallest radius);  margin [m]: list skin beyond the gap (None: 0.2 mean radius)
    tolerance [-], max_iterations: the NLGS convergence (solver.py).

    After each run: ``last_iterations`` and ``last_residual`` of the last step,
    ``mean_iterations`` over all steps, ``not_converged`` (steps whose residual stayed
    above the tolerance after max_iterations sweeps; a run that adds some warns,
    RuntimeWarning, with ``worst_residual``).
    """

    GRAVITY_SLOTS = st.GX
    LOSS_SLOTS = (st.DISS_N, st.DISS_T, st.WALL_WORK)

    rigid = True        # rigid grains (engine.Engine.rigid)

    def __init__(self, state, materials, walls=(), periodic=(), gravity=(0.0, 0.0, -9.81),
                 dt=None, theta=0.5, gap=None, margin=None, tolerance=1e-4,
                 max_iterations=1000):
        self.state = state
        self.materials = list(materials) if materials else [Material()]
        n_mat = len(self.materials)
        if state.materials.size and (state.materials.min() < 0
                                     or state.materials.max() >= n_mat):
            raise ValueError(f"grain material ids must be in 0..{n_mat - 1}")
        self.walls = walls if isinstance(walls, Walls) else Walls(walls, periodic)
        if np.any(self.walls.material >= n_mat):
            raise ValueError(f"wall material ids must be in 0..{n_mat - 1}")
        gravity = checked_gravity(gravity, state.dim)
        self.tables = material_tables(self.materials)
        if dt is None:
            dt = suggested_time_step(state, gravity)["suggested_dt_s"]
        if not (0.5 <= theta <= 1.0):
            raise ValueError(f"theta must be in [0.5, 1], got {theta}")
        gap = 0.1 * float(state.radii.min()) if gap is None else gap
        margin = 0.2 * float(state.radii.mean()) if margin is None else margin
        for name, value in (("dt", dt), ("gap", gap), ("margin", margin),
                            ("tolerance", tolerance)):
            if not (value > 0 and math.isfinite(value)):
                raise ValueError(f"{name} must be a positive number, got {value}")
        if max_iterations < 1:
            raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
        for d in range(3):
            if self.walls.periodic_flag[d] and self.walls.periodic_length[d] < \
                    2 * (2 * state.radii.max() + gap + margin):
                raise ValueError(f"periodic length along axis {d} must be at least twice "
                                 "the largest diameter plus gap and margin")
        self.clock = np.zeros(st.NCLOCK)
        self.clock[[st.TIME, st.DT, st.THETA, st.GAP, st.MARGIN, st.TOLERANCE]] = \
            state.time, dt, theta, gap, margin, tolerance
        self.clock[st.GX:st.GZ + 1] = gravity
        self.counters = np.zeros(st.NCOUNTERS, np.int64)
        self.counters[st.STEP] = self.counters[st.FIRST_STEP] = state.step
        self.counters[st.MAX_ITERATIONS] = max_iterations
        self.counters[st.FORCE_REBUILD] = 1
        n = state.n
        self.reference_positions = state.positions.copy()
        self.reference_offset = self.walls.offset.copy()
        self._solved = np.zeros((len(self.walls), 10))
        self._push = np.zeros(len(self.walls))
        self.old_velocities = np.zeros((n, 3))
        self.old_angular_velocities = np.zeros((n, 3))
        self._allocate(2 * n + 64, n // 4 + 16)

    def _allocate(self, pairs, wall_candidates, keep=False):
        """(Re)allocate the lists and work space, keeping the lists when ``keep``."""
        old = self.lists if keep else None
        self.lists = new_lists(self.state.n, pairs, wall_candidates, old)
        self.work = new_work(pairs, wall_candidates)

    # ------------------------------------------------------------------ bundles
    def _grains(self):
        s = self.state
        free = s.fixed == 0
        return Grains(positions=s.positions, velocities=s.velocities,
                      angular_velocities=s.angular_velocities, orientations=s.orientations,
                      radii=s.radii, masses=s.masses, inertias=s.inertias,
                      inv_mass=np.where(free, 1.0 / s.masses, 0.0),
                      inv_inertia=np.where(free, 1.0 / s.inertias, 0.0),
                      materials=s.materials, fixed=s.fixed,
                      reference_positions=self.reference_positions,
                      old_velocities=self.old_velocities,
                      old_angular_velocities=self.old_angular_velocities)

    def _walls(self):
        w = self.walls
        return WallBundle(kind=w.kind, geometry=w.geometry, offset=w.offset, base=w.base,
                          velocity=w.velocity, force=w.force, motion_kind=w.motion_kind,
                          motion=w.motion, material=w.material,
                          reference_offset=self.reference_offset, solved=self._solved,
                          push=self._push)

    def _periodic(self):
        return self.walls.periodic_box()

    # ------------------------------------------------------------------ running
    @property
    def dt(self):
        """Time step [s]."""
        return float(self.clock[st.DT])

    @property
    def theta(self):
        """The theta of the Moreau-Jean step [-] (stepping.py)."""
        return float(self.clock[st.THETA])

    @property
    def time(self):
        """Simulated time [s]."""
        return float(self.clock[st.TIME])

    @property
    def step(self):
        """Steps done."""
        return int(self.counters[st.STEP])

    @property
    def last_iterations(self):
        """NLGS sweeps of the last step."""
        return int(self.counters[st.ITERATIONS])

    @property
    def last_residual(self):
        """Convergence residual of the last step [-] (solver.py)."""
        return float(self.clock[st.RESIDUAL])

    @property
    def mean_iterations(self):
        """NLGS sweeps per step since the start (0 before the first step)."""
        steps = self.step - int(self.counters[st.FIRST_STEP])
        return float(self.counters[st.TOTAL_ITERATIONS]) / steps if steps > 0 else 0.0

    @property
    def not_converged(self):
        """Steps whose NLGS residual stayed above the tolerance after max_iterations."""
        return int(self.counters[st.NOT_CONVERGED])

    @property
    def worst_residual(self):
        """The largest residual of a step that did not converge (0 when all did)."""
        return float(self.clock[st.WORST_RESIDUAL])

    def _chunk(self, nsteps):
        total = 0
        while True:
            status, done = st.advance(self._grains(), self.lists, self._walls(),
                                      self._periodic(), self.tables, self.work, self.clock,
                                      self.counters, nsteps)
            total += done
            nsteps -= done
            self.state.time = self.time
            self.state.step = self.step
            if status != st.GROW:
                return status, total
            need_p = int(self.counters[st.NEED_PAIRS])
            need_w = int(self.counters[st.NEED_WALLS])
            self._allocate(max(int(1.3 * need_p) + 64, self.lists.partners.size),
                           max(int(1.3 * need_w) + 16, self.lists.wall_ids.size), keep=True)

    def run(self, steps=None, time=None, until=None, every=(), max_chunk=20000,
            between=None):
        """Advance ``steps`` steps or ``time`` seconds (engine.Engine.run: the run ends at
        the first step end not before the time), or until ``until`` (MaxSpeedBelow,
        EnergyRatioBelow, tested after every step) holds.  ``every``: (trigger,
        callback(engine)) pairs run where their Periodic falls; ``between``:
        callback(engine) after every chunk, True stops the run.  Returns "done",
        "condition" or "stopped"; SimulationError on non-finite positions or velocities.
        Warns (RuntimeWarning) when some step of the run did not converge."""
        if steps is None and time is None:
            raise ValueError("run needs steps= or time= (an upper bound, also with until=)")
        if steps is None:
            steps = int(math.ceil(time / self.dt - 1e-6))
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps}")
        periods = {p: p.period(self.dt) for trigger, _ in every for p in pauses(trigger)}
        end = self.step + steps
        failed = self.not_converged
        self.counters[st.COND_KIND] = until.kind if until is not None else NO_CONDITION
        self.clock[st.COND_VALUE] = until.value if until is not None else 0.0
        try:
            while self.step < end:
                n = min(end - self.step, max_chunk)
                for period in periods.values():
                    n = min(n, period - self.step % period)
                status, _ = self._chunk(n)
                for trigger, cb in every:
                    if trigger.fires(lambda p: self.step % periods[p] == 0, self.time):
                        cb(self)
                if status == CONDITION:
                    return "condition"
                if status == NAN:
                    raise SimulationError(
                        f"non-finite position or velocity at step {self.step} (t = "
                        f"{self.time:.6g} s): the contact solve failed (see not_converged "
                        "and last_residual) or grains started inside each other")
                if between is not None and between(self):
                    return "stopped"
        finally:
            self.counters[st.COND_KIND] = NO_CONDITION
            if self.not_converged > failed:
                warnings.warn(
                    f"contact dynamics: {self.not_converged - failed} steps of this run "
                    f"did not converge within {int(self.counters[st.MAX_ITERATIONS])} NLGS "
                    f"sweeps (worst residual {self.worst_residual:.3g} against the "
                    f"tolerance {self.clock[st.TOLERANCE]:.3g})", RuntimeWarning,
                    stacklevel=2)
        return "done"

    # ------------------------------------------------------------------ snapshots
    def _arrays(self):
        arrays = {f"grains/{k}": v for k, v in self.state.arrays().items()}
        arrays.update({f"lists/{k}": v for k, v in self.lists._asdict().items()
                       if not k.startswith("scratch_") and k not in _TRANSIENT})
        w = self.walls
        arrays.update({"walls/offset": w.offset, "walls/base": w.base,
                       "walls/velocity": w.velocity, "walls/force": w.force,
                       "walls/motion_kind": w.motion_kind, "walls/motion": w.motion,
                       "loop/reference_positions": self.reference_positions,
                       "loop/reference_offset": self.reference_offset,
                       "loop/clock": self.clock, "loop/counters": self.counters})
        return arrays

    def snapshot(self):
        """Every mutable array of the run by name (copies): grains, the contact lists
        with the impulses of the last step (the solver's warm start), walls, clock and
        counters; ``restore`` of it continues the run bit for bit."""
        return {k: np.array(v, copy=True) for k, v in self._arrays().items()}

    def restore(self, arrays):
        """Put a ``snapshot`` back (an engine built from the same inputs); ValueError
        naming what is missing or does not fit.  A snapshot whose impulses have three
        columns (written before rolling resistance) restores with zero couples."""
        missing = [k for k in self._arrays() if k not in arrays]
        if missing:
            raise ValueError(f"snapshot lacks {missing}")
        arrays = dict(arrays)
        for name in ("lists/impulses", "lists/wall_impulses"):
            old = np.asarray(arrays[name])
            if old.ndim == 2 and old.shape[1] == 3:
                arrays[name] = np.hstack([old, np.zeros_like(old)])
        pairs = np.asarray(arrays["lists/partners"]).size
        wall_candidates = np.asarray(arrays["lists/wall_ids"]).size
        self._allocate(pairs, wall_candidates)
        copy_into(self._arrays(), arrays)
        # the transient arrays are rewritten before use; the reverse lists by a rebuild
        self.state.time = self.time
        self.state.step = self.step

    # ------------------------------------------------------------------ contacts
    def _touching(self, start, impulses):
        n = self.state.n
        m = int(start[n])
        touching = np.any(impulses[:m] != 0.0, axis=1)
        return touching, impulses[:m, :3][touching] / self.dt

    def contacts(self):
        """The grain pairs that carried an impulse in the last step (engine.Contacts):
        force = impulse / dt [N], split along the normal the impulse acted on (from the
        centres at the start of the step); the contact point divides the present
        separation r_i - r_j in proportion to the radii (branch_i = -R_i (r_i - r_j) /
        (R_i + R_j)), so that branch_j - branch_i = r_i - r_j."""
        touching, force = self._touching(self.lists.start, self.lists.impulses)
        m = touching.size
        i = self.lists.owner[:m][touching].astype(np.int64)
        j = self.lists.partners[:m][touching].astype(np.int64)
        normal = self.lists.normal[:m][touching]
        s = self.state
        separation = self.walls.minimum_image(s.positions[i] - s.positions[j])
        r_i, r_j = s.radii[i], s.radii[j]
        share = (r_i / (r_i + r_j))[:, None]
        normal_force = np.einsum("ka,ka->k", force, normal)
        return Contacts(i, j, -share * separation, (1.0 - share) * separation,
                        normal_force, force - normal_force[:, None] * normal, normal)

    def wall_contacts(self):
        """The grain-wall contacts that carried an impulse in the last step
        (engine.WallContacts), force = impulse / dt [N] split along the normal it acted
        on; the contact point is the foot of the grain's centre on the wall."""
        touching, force = self._touching(self.lists.wall_start, self.lists.wall_impulses)
        m = touching.size
        grain = self.lists.wall_owner[:m][touching].astype(np.int64)
        wall = self.lists.wall_ids[:m][touching].astype(np.int64)
        distance, _ = self.walls.distances(self.state.positions[grain], wall)
        normal = self.lists.wall_normal[:m][touching]
        normal_force = np.einsum("ka,ka->k", force, normal)
        return WallContacts(grain, wall, -distance[:, None] * normal, normal_force,
                            force - normal_force[:, None] * normal, normal)

    # ------------------------------------------------------------------ changes by hand
    def _forget(self, chosen):
        """Zero the impulses of every listed contact of the grains ``chosen`` (N,) bool."""
        n = self.state.n
        lists = self.lists
        m, q = int(lists.start[n]), int(lists.wall_start[n])
        stale = chosen[lists.owner[:m]] | chosen[lists.partners[:m]]
        lists.impulses[:m][stale] = 0.0
        lists.wall_impulses[:q][chosen[lists.wall_owner[:q]]] = 0.0
        self.counters[st.FORCE_REBUILD] = 1

    def relocate(self, indices, positions, velocities, angular_velocities=None):
        """Move grains ``indices`` to ``positions`` (K, 3) [m] with ``velocities`` (K, 3)
        [m/s] and ``angular_velocities`` (K, 3) [rad/s] (None: zero)
        (engine.Engine.relocate): their contacts' impulses are forgotten (no warm start
        from the old place) and the lists are rebuilt before the next step."""
        s = self.state
        idx = s.move(indices, positions, velocities, angular_velocities)
        if idx.size == 0:
            return
        chosen = np.zeros(s.n, bool)
        chosen[idx] = True
        self._forget(chosen)

    def set_motion(self, wall, motion):
        """Prescribe ``motion`` (walls.Motion) to ``wall`` from now on
        (engine.Engine.set_motion).  A "piston" (a wall of a mass driven by an applied
        force) has its velocity solved with the contact impulses of each step
        (solver.solved_velocity): its momentum balance is implicit, so it rests on
        rigid grains at once, without bouncing on a stiffness that is not there."""
        self.walls.prescribe(self.walls.index(wall), motion, self.time)

    def set_servo(self, wall, *, force=None, stress=None, gain=None, time_constant=None,
                  stiffness=None, max_speed=None, direction=None):
        """Make ``wall`` a servo (stress-controlled) wall or change its settings
        (engine.Engine.set_servo): target ``force`` [N] or ``stress`` [Pa] times the
        wall's area, gain ``gain`` [m/(N s)] or 1/(``stiffness`` [N/m] ``time_constant``
        [s]), largest speed ``max_speed`` [m/s], ``direction`` into the grains; a setting
        not given keeps its value on a servo wall.  The wall's velocity is solved with
        the contact impulses of each step (solver.solved_velocity), so against rigid
        grains at rest it carries the target at once."""
        self.set_motion(wall, self.walls.servo(
            wall, force=force, stress=stress, gain=gain, time_constant=time_constant,
            stiffness=stiffness, max_speed=max_speed, direction=direction))

    def place_wall(self, wall, offset):
        """Put ``wall`` at ``offset`` (3,) [m] from where it was built, at once
        (engine.Engine.place_wall); the lists are rebuilt before the next step."""
        self.walls.place(wall, offset)
        self.counters[st.FORCE_REBUILD] = 1
