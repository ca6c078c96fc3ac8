"""Simulation: state + materials + contact model + walls + integrator, run in compiled
chunks with Python triggers in between.

>>> sim = Simulation(state, [Material(...)], ContactModel("hertz", "tsuji", "mindlin"),
...                  walls=box((0, 0, 0), (L, L, H)), dt=1e-6)      # doctest: +SKIP
>>> sim.run(time=0.5, until=MaxSpeedBelow(1e-3))                      # doctest: +SKIP
"""
import dataclasses
import math

import numba
import numpy as np

from ...core.engine import (Contacts, ImageContacts, OverlapError, SimulationError,
                            WallContacts, checked_gravity, gravitational_energy,
                            kinetic_energy)
from ...core.neighbors import list_owners
from ...core.species import ContactModel, Material
from ...core.symmetry import MASKS, SymmetryPlanes, rebuild_images
from ...core.triggers import NO_CONDITION, pauses
from ...core.walls import Walls
from ...physics.registry import HISTORY, MODES, PLANAR, PLANAR_SPRINGS
from . import energy, loop
from .bundles import Grains, Images, Pairs, WallPairs, wall_bundle
from .contacts import block_count
from .integrators import SCHEMES, SLOTS, history_names, integrator_id
from .law_loop import law_address, prepare, workspace as law_workspace
from .planar import planar_address
from .timestep import time_step_report


# the lists' arrays are checkpointed by their field names (bundles.Pairs, WallPairs):
# "pairs/start", "wall_contacts/ids"...; rewritten by every force evaluation before it is read: not part of a snapshot
_TRANSIENT = ("pairs/own",)


# the orientations the loop sees when they are not followed (passes.turn)
_NOT_TURNED = np.zeros((0, 4))


def _with_touching_marks(arrays, width):
    """A snapshot written before collisions were counted (``counters`` shorter than
    loop.NCOUNTERS), brought up to date: the collision counters at zero, and each
    contact history row widened to ``width`` columns, its touching mark (the last,
    contacts.touch) set where the contact's force of the last evaluation is not zero."""
    arrays = dict(arrays)
    counters = np.asarray(arrays["loop/counters"])
    arrays["loop/counters"] = np.pad(counters, (0, loop.NCOUNTERS - counters.size))
    for group in ("pairs", "wall_contacts"):
        history = np.asarray(arrays[f"{group}/history"])
        history = np.pad(history, ((0, 0), (0, width - history.shape[1])))
        history[:, -1] = np.any(np.asarray(arrays[f"{group}/force"]) != 0.0, axis=1)
        arrays[f"{group}/history"] = history
    return arrays


def _with_planar_springs(arrays, model, offset):
    """A 2D snapshot written when the tangential springs of disks were vectors (it has
    no "loop/springs" entry), brought up to date: each contact's elongation zeta
    (history columns ``offset`` to ``offset`` + 2) made the scalar along s = z x n of
    physics.tangential.tangential_planar_spring_force, when ``model`` (ContactModel)
    has such a spring.  The normal is read from the contact's last force f, whose
    normal part pushes the grain away (f_n > 0): with zeta = zeta_s s,
    f.(z x zeta) = -zeta_s f_n, so zeta_s = -sign(f.(z x zeta)) |zeta|.  A contact
    whose force is zero, or along its spring, loses the spring."""
    arrays = dict(arrays, **{"loop/springs": np.array([1])})
    if model.tangential not in PLANAR_SPRINGS:
        return arrays
    for group in ("pairs", "wall_contacts", "images"):
        if f"{group}/history" not in arrays:
            continue
        history = np.array(arrays[f"{group}/history"], dtype=np.float64)
        force = np.asarray(arrays[f"{group}/force"])
        zx, zy = history[:, offset].copy(), history[:, offset + 1].copy()
        across = force[:, 0] * -zy + force[:, 1] * zx
        history[:, offset] = -np.sign(across) * np.hypot(zx, zy)
        history[:, offset + 1:offset + 3] = 0.0
        arrays[f"{group}/history"] = history
    return arrays


class Simulation:
    """A soft-particle DEM simulation (SI units), the soft engine of core/engine.py:
    protocols, analysis and outputs use it through that interface (state, walls, time,
    gravity, run, contacts, wall_contacts, energies, snapshot/restore, relocate,
    set_motion, set_servo, place_wall); ``steps=`` runs, ``dt``, ``step``, the
    ``collisions`` and ``wall_collisions`` counts and the kernel arrays (``pairs``,
    ``wall_pairs``: the neighbour and wall-contact lists, bundles.Pairs and WallPairs,
    arrays by name; ``clock``, ``counters``) are its own.

    state : State;  materials : list of Material (grain and wall materials by index)
    model : ContactModel;  walls : list of Plane/Cylinder;  periodic : list of Periodic
    symmetry : list of core.symmetry.Symmetry planes (CPU only): the grains near one
      touch the mirror images of the grains near it (image_contacts.py)
    gravity : (3,) [m/s^2];  dt [s] (None: the suggested step);  skin [m] (None: 0.1 of
    the mean diameter);  allow_large_dt: accept a step above the safe fraction.
    overlap_limit : stop when some overlap exceeds this fraction of the smaller radius.
    check_interval : steps between NaN/overlap/stop-condition checks.
    integrator : one of integrators.NAMES (integrators/ids.py lists each with its equation).
    backend : "cpu" (compiled loops, numba threads) or "gpu" (engines/soft/gpu/engine.py: the same
      step on an NVIDIA GPU; the arrays travel to the device and back once per chunk).
    orientations : False leaves state.orientations as they are on the CPU: spheres
      and disks turn without their orientation acting on anything, and turning each
      grain every step costs about 8 ns (a tenth of a step of a 1 000-grain bed).  The
      GPU always turns them (False is ignored there), so one config runs on both.

    Everything a run needs to continue exactly:
      state arrays (State.arrays()), ``integrator_state`` (the integrator's per-grain
      history by name, e.g. previous_accelerations for beeman, jerks/snaps/crackles
      for gear6: views into one (slots, N, 3) array, translational then angular_),
      ``clock`` (float64: time, dt, energies...) and ``counters`` (int64: step,
      integrator history length, collisions...), the neighbour and wall-contact lists with their
      contact histories, and the wall arrays.  ``snapshot()`` copies all of them into
      one dict of numpy arrays and ``restore(dict)`` puts them back into a Simulation
      built with the same arguments; the continued run is then bitwise identical to an
      uninterrupted one (same thread count).
    """

    rigid = False        # soft grains (engine.Engine.rigid)

    def __init__(self, state, materials, model=None, walls=(), periodic=(),
                 gravity=(0.0, 0.0, -9.81), dt=None, skin=None, integrator="velocity_verlet",
                 allow_large_dt=False, overlap_limit=0.2, check_interval=100, backend="cpu",
                 orientations=True, symmetry=()):
        if backend not in ("cpu", "gpu"):
            raise ValueError(f"backend must be 'cpu' or 'gpu', got {backend!r}")
        self.orientations = bool(orientations) or backend == "gpu"
        if backend == "gpu":
            from .gpu import unavailable
            reason = unavailable()
            if reason:
                raise ValueError(f"backend 'gpu': {reason}")
        self.backend = backend
        self._device = None
        self._law = None            # the CPU's batched law (engines/soft/law_loop.py), when used
        self.state = state
        self.materials = list(materials) if materials else [Material()]
        self.model = model or ContactModel()
        n_mat = len(self.materials)
        if state.materials.size and (state.materials.min() < 0 or state.materials.max() >= n_mat):
            raise ValueError(f"grain material ids must be in 0..{n_mat - 1}")
        self.walls = walls if isinstance(walls, Walls) else Walls(walls, periodic)
        if np.any(self.walls.material >= n_mat):
            raise ValueError(f"wall material ids must be in 0..{n_mat - 1}")
        self.symmetry = symmetry if isinstance(symmetry, SymmetryPlanes) else \
            SymmetryPlanes(symmetry, state.dim, self.walls.periodic_flag)
        if self.symmetry and backend == "gpu":
            raise ValueError("symmetry planes run on the CPU backend only: the GPU has no "
                             "image contacts")
        gravity = checked_gravity(gravity, state.dim)
        self.params = self.model.pair_table(self.materials, state.dim)
        self.model_ids = self.model.ids(state.dim)
        self.dt_report = time_step_report(state, self.materials, self.model, dt, integrator)
        if dt is None:
            dt = self.dt_report["suggested_dt_s"]
            self.dt_report.update(dt_s=dt, fraction=dt / self.dt_report["critical_time_s"])
        if not dt > 0:
            raise ValueError(f"time step must be > 0 [s], got {dt}")
        if self.dt_report["fraction"] > self.dt_report["max_fraction"] and not allow_large_dt:
            r = self.dt_report
            raise ValueError(
                f"time step {dt:.3g} s is {r['fraction']:.2f} of the {r['criterion']} "
                f"{r['critical_time_s']:.3g} s, above the safe fraction {r['max_fraction']}"
                + (f" ({r['limit']})" if "limit" in r else "") + "; "
                f"use dt <= {r['max_fraction'] * r['critical_time_s']:.3g} s (suggested "
                f"{r['suggested_dt_s']:.3g} s) or pass allow_large_dt=True")
        if skin is None:
            skin = 0.2 * float(state.radii.mean())
        if not skin > 0:
            raise ValueError(f"skin must be > 0 [m], got {skin}")
        for d in range(3):
            if self.walls.periodic_flag[d] and \
                    self.walls.periodic_length[d] < 2 * (2 * state.radii.max() + skin):
                raise ValueError(f"periodic length along axis {d} must be at least twice the "
                                 "largest diameter plus skin")
        if check_interval < 1 or not overlap_limit > 0:
            raise ValueError("check_interval must be >= 1 and overlap_limit > 0")
        self.clock = loop.new_clock(dt, skin, gravity)
        self.clock[loop.TIME] = state.time
        self.clock[loop.OVERLAP_LIMIT] = overlap_limit
        self.counters = np.zeros(loop.NCOUNTERS, np.int64)
        self.counters[loop.STEP] = state.step
        self.counters[loop.DIM] = state.dim
        self.counters[loop.INTEGRATOR] = integrator_id(integrator)
        self.counters[loop.FORCE_REBUILD] = 1
        self.counters[loop.CHECK_INTERVAL] = check_interval
        self.integrator = integrator
        n = state.n
        self.reference_positions = state.positions.copy()
        self.max_overlap = np.zeros(n)
        self.block_scratch = np.zeros(block_count(n, numba.get_num_threads()))
        # the model's history values, then the touching mark of each contact (contacts.touch)
        self.history_size = max(3, self.model.history_size + 1)
        # start small: the first build grows the lists to 1.3 x what it needs
        self._allocate_pairs(2 * n + 64)
        self._allocate_walls(n // 4 + 16)
        self._allocate_images(n // 4 + 16 if self.symmetry else 0)
        self._allocate_integrator()

    # ------------------------------------------------------------------ storage
    def _allocate_pairs(self, capacity):
        """(Re)allocate pair arrays with room for ``capacity`` pairs, keeping the list.

        Grain indices loaded from these arrays are unsigned: numba then skips the
        negative-index wraparound on every array access in the contact loops."""
        n, h = self.state.n, self.history_size
        old = getattr(self, "pairs", None)
        start = old.start if old is not None else np.zeros(n + 1, np.int64)
        partners = np.zeros(capacity, np.uint32)
        history = np.zeros((capacity, h))
        if old is not None:
            m = int(old.start[n])
            partners[:m] = old.partners[:m]
            history[:m] = old.history[:m]
        self.pairs = Pairs(start=start, partners=partners, history=history,
                           scratch_start=np.zeros(n + 1, np.int64),
                           scratch_partners=np.zeros(capacity, np.uint32),
                           scratch_history=np.zeros((capacity, h)),
                           reverse_start=np.zeros(n + 1, np.int64),
                           reverse_pairs=np.zeros(capacity, np.uint32),
                           force=np.zeros((capacity, 3)), own=np.zeros((n, 6)),
                           torque_j=np.zeros((capacity, 3)))

    def _allocate_walls(self, capacity):
        n, h, w = self.state.n, self.history_size, self.walls
        old = getattr(self, "wall_pairs", None)
        start = old.start if old is not None else np.zeros(n + 1, np.int64)
        ids = np.zeros(capacity, np.uint32)
        history = np.zeros((capacity, h))
        if old is not None:
            m = int(old.start[n])
            ids[:m] = old.ids[:m]
            history[:m] = old.history[:m]
        self.wall_pairs = WallPairs(start=start, ids=ids, history=history,
                                    scratch_start=np.zeros(n + 1, np.int64),
                                    scratch_ids=np.zeros(capacity, np.uint32),
                                    scratch_history=np.zeros((capacity, h)),
                                    force=np.zeros((capacity, 3)),
                                    torque=np.zeros((capacity, 3)))
        self.reference_offset = w.offset.copy()

    def _allocate_images(self, capacity):
        """(Re)allocate the image-candidate arrays (bundles.Images) with room for
        ``capacity`` candidates, keeping the list."""
        n, h = self.state.n, self.history_size
        old = getattr(self, "images", None)
        start = old.start if old is not None else np.zeros(n + 1, np.int64)
        ids = np.zeros(capacity, np.uint32)
        history = np.zeros((capacity, h))
        force = np.zeros((capacity, 3))
        torque = np.zeros((capacity, 3))
        if old is not None:
            m = int(old.start[n])
            for new, was in ((ids, old.ids), (history, old.history), (force, old.force),
                             (torque, old.torque)):
                new[:m] = was[:m]
        self.images = Images(flag=self.symmetry.flag, at=self.symmetry.at, start=start,
                             ids=ids, history=history, scratch_start=np.zeros(n + 1, np.int64),
                             scratch_ids=np.zeros(capacity, np.uint32),
                             scratch_history=np.zeros((capacity, h)), force=force,
                             torque=torque)

    def _rebuild_images(self):
        """Rebuild the image-candidate list at the current positions (core.symmetry),
        growing it as needed; nothing to do without symmetry planes."""
        if not self.symmetry:
            return
        w = self.walls
        while True:
            im = self.images
            needed = rebuild_images(self.state.positions, self.state.radii, self.skin,
                                    w.periodic_flag, w.periodic_lo, w.periodic_length,
                                    im.flag, im.at, im.start, im.ids, im.history,
                                    im.scratch_start, im.scratch_ids, im.scratch_history)
            if needed <= im.ids.size:
                return
            self._allocate_images(int(1.3 * needed) + 16)

    def _allocate_integrator(self):
        """The integrator's per-grain history, zero: ``integrator_history`` (slots, N, 3),
        exposed by slot name in ``integrator_state`` (views, so restore writes through)."""
        k = integrator_id(self.integrator)
        self.integrator_history = np.zeros((2 * SLOTS[k], self.state.n, 3))
        self.integrator_state = dict(zip(history_names(self.integrator),
                                         self.integrator_history))
        self.counters[loop.HISTORY_STEPS] = 0

    def reset_integrator_history(self):
        """Start the integrator afresh from the current state at the next run: call it
        after changing positions or velocities by hand between runs, which verlet,
        leap_frog, beeman and the Gear schemes otherwise carry in their history (forces
        and accelerations are evaluated again first)."""
        self._allocate_integrator()
        self.counters[loop.PRIMED] = 0

    def _start_derivatives(self, steps=8):
        """Exact start-up of the Gear schemes (integrators/gear.py): integrate ``steps``
        steps forward and as many back to the start, ``start_sweeps`` times, keeping the
        higher derivatives the corrector builds up and putting back everything else."""
        sweeps = SCHEMES[integrator_id(self.integrator)].start_sweeps
        if sweeps == 0:
            return
        saved = self.snapshot()
        dt = self.clock[loop.DT]
        for _ in range(sweeps):
            for sign in (1.0, -1.0):
                self.clock[loop.DT] = sign * dt
                self._chunk(steps)
            derivatives = self.integrator_history.copy()
            self.restore(saved)
            self.integrator_history[...] = derivatives

    def _grains(self):
        """The grains as the kernels see them (bundles.Grains)."""
        s = self.state
        return Grains(positions=s.positions, velocities=s.velocities,
                      angular_velocities=s.angular_velocities,
                      orientations=s.orientations if self.orientations else _NOT_TURNED,
                      forces=s.forces, torques=s.torques, accelerations=s.accelerations,
                      angular_accelerations=s.angular_accelerations, radii=s.radii,
                      masses=s.masses, inertias=s.inertias, materials=s.materials,
                      fixed=s.fixed, reference_positions=self.reference_positions,
                      max_overlap=self.max_overlap)

    def _walls(self):
        """The walls and their contact list as the kernels see them (bundles.WallBundle)."""
        return wall_bundle(self.walls, self.reference_offset, self.wall_pairs)

    def _periodic(self):
        """The periodic directions (core.walls.PeriodicBox)."""
        return self.walls.periodic_box()

    # ------------------------------------------------------------------ running
    @property
    def dt(self):
        """Time step [s]."""
        return float(self.clock[loop.DT])

    @property
    def skin(self):
        """Neighbour-list skin [m]: lists hold the pairs closer than the sum of radii plus
        this, and are rebuilt when some grain may have moved more than half of it."""
        return float(self.clock[loop.SKIN])

    @property
    def time(self):
        """Simulated time [s]."""
        return float(self.clock[loop.TIME])

    @property
    def step(self):
        """Steps done."""
        return int(self.counters[loop.STEP])

    @property
    def rebuilds(self):
        """Neighbour-list builds so far."""
        return int(self.counters[loop.REBUILDS])

    @property
    def collisions(self):
        """Grain-pair collisions since the start [-]: pairs found touching (overlap > 0) at
        a force evaluation of a step when they were not at the one before, counted in
        the compiled loop (loop.COLLISIONS, contacts.touch).  A pair in lasting contact
        counts once, also over neighbour rebuilds; the contacts found by the evaluation
        that starts the loop afresh (the first of a run, then after relocate, hold or a
        change of gravity) were there already and count none.  A collision rate is its
        change over a time interval divided by that interval [1/s].  Counted on the CPU
        only: None on the GPU backend."""
        return self._collisions(loop.COLLISIONS)

    @property
    def wall_collisions(self):
        """Grain-wall collisions since the start [-], counted as ``collisions`` is (one per
        grain and wall whose contact starts; loop.WALL_COLLISIONS)."""
        return self._collisions(loop.WALL_COLLISIONS)

    def _collisions(self, slot):
        """counters[slot] as an int; None on the GPU, whose loop does not count."""
        if self.backend == "gpu":
            return None
        return int(self.counters[slot])

    @property
    def dissipated(self):
        """Energy dissipated so far [J]: {"normal": ..., "tangential": ...}."""
        return {"normal": float(self.clock[loop.DISS_N]),
                "tangential": float(self.clock[loop.DISS_T])}

    @property
    def wall_work(self):
        """Work done on the grains by moving walls so far [J]."""
        return float(self.clock[loop.WALL_WORK])

    def _chunk(self, nsteps):
        """Run up to nsteps compiled steps, growing storage as needed."""
        if self.backend == "gpu":
            from .gpu.batch import current
            batch = current()
            if batch is not None:            # one job of a gpu.batch.Batch
                return batch.chunk(self, nsteps)
            if self._device is None:
                from .gpu.engine import DeviceEnsemble
                self._device = DeviceEnsemble([self])
            status, done = self._device.chunk([nsteps])
            return int(status[0]), int(done[0])
        blocks = block_count(self.state.n, numba.get_num_threads())
        if self.block_scratch.size != blocks or self._law is None:  # first, or new threads
            self.block_scratch = np.zeros(blocks)
            self._law = law_workspace(
                law_address(self.model_ids), blocks, self.history_size,
                planar_address(self.model_ids) if self.state.dim == 2 else 0)
        total = 0
        while True:
            self._law = prepare(self._law, self.params, self.pairs.partners.size)
            # the grains of the pair and wall walks (kept by each rebuild), whatever set the lists
            list_owners(self.pairs.start, self.state.n, self.pairs.scratch_partners)
            list_owners(self.wall_pairs.start, self.state.n, self.wall_pairs.scratch_ids)
            list_owners(self.images.start, self.state.n, self.images.scratch_ids)
            status, done = loop.run_chunk(self.model_ids, self.params, self._law, self._grains(),
                                          self.pairs, self._walls(), self._periodic(),
                                          self.images, self.clock, self.counters,
                                          self.integrator_history, self.block_scratch, nsteps)
            total += done
            self.state.time = self.time
            self.state.step = self.step
            if status != loop.RELIST:
                return status, total
            status = self._relist()
            if status != loop.DONE:
                return status, total
            nsteps -= done

    def _relist(self):
        """Rebuild the neighbour lists (loop.relist) and the image candidates, growing
        them as needed; returns DONE or NAN."""
        while True:
            status = loop.relist(self._grains(), self.pairs, self._walls(), self._periodic(),
                                 self.clock, self.counters, self._law)
            if status == loop.DONE:
                self._rebuild_images()
            if status != loop.GROW:
                return status
            need_p = int(self.counters[loop.NEED_PAIRS])
            need_w = int(self.counters[loop.NEED_WALLS])
            if need_p > self.pairs.partners.size:
                self._allocate_pairs(int(1.3 * need_p) + 64)
            if need_w > self.wall_pairs.ids.size:
                self._allocate_walls(int(1.3 * need_w) + 16)

    def run(self, steps=None, time=None, until=None, every=(), max_chunk=20000,
            between=None):
        """Advance ``steps`` steps or ``time`` seconds (engine.Engine.run: the run ends
        at the first step end not before the time), or until the compiled condition
        ``until`` (MaxSpeedBelow, EnergyRatioBelow) holds, whichever comes first.

        every : list of (trigger, callback(sim)) (core.triggers: Periodic, or their
            compositions), each callback run between chunks when its trigger fires.
        between : callback(sim) run after every chunk; returning True stops the run
            ("stopped").  Chunks end on multiples of check_interval (or where a trigger
            or the end falls), so the stop condition is tested at the same steps however
            the run is cut: a run stopped and resumed gives the same numbers.
        Returns "done", "condition" or "stopped"; raises SimulationError on NaN or
        blow-up.
        """
        periods = {p: p.period(self.dt) for trigger, _ in every for p in pauses(trigger)}

        def due(periodic):
            return self.step % periods[periodic] == 0
        end = self.begin_run(steps, time, until)
        try:
            while self.step < end:
                status, _ = self._chunk(self.chunk_size(end, max_chunk,
                                                        list(periods.values())))
                for trigger, cb in every:
                    if trigger.fires(due, self.time):
                        cb(self)
                if status == loop.CONDITION:
                    return "condition"
                error = self.failure(status)
                if error is not None:
                    raise error
                if between is not None and between(self):
                    return "stopped"
        finally:
            self.counters[loop.COND_KIND] = NO_CONDITION
        return "done"

    def begin_run(self, steps, time, until):
        """Set up a run of ``steps`` steps or ``time`` seconds with the stop condition
        ``until`` (the Gear schemes' start-up runs here); returns the step it ends at.
        The caller sets COND_KIND back to NO_CONDITION when the run ends."""
        if steps is None and time is None:
            raise ValueError("run needs steps= or time= (an upper bound, also with until=)")
        if steps is None:
            # a deadline at most 1e-6 of a step past a step end ends there: a deadline
            # kept as simulated time then falls on the same step whatever the time a
            # run resumes from (summed steps differ from steps x dt by rounding)
            steps = int(math.ceil(time / self.dt - 1e-6))
        if steps < 0:
            raise ValueError(f"steps must be >= 0, got {steps}")
        if self.counters[loop.HISTORY_STEPS] == 0 and steps > 0:
            self._start_derivatives()
        self.counters[loop.COND_KIND] = until.kind if until is not None else NO_CONDITION
        self.clock[loop.COND_VALUE] = until.value if until is not None else 0.0
        return self.step + steps

    def failure(self, status):
        """The SimulationError for a run_chunk status code (NAN, OVERLAP) at the current
        step, with what to check; None for the others."""
        if status == loop.NAN:
            report = self.dt_report
            return SimulationError(
                f"non-finite position, velocity or force at step {self.step} "
                f"(t = {self.time:.6g} s): the time step may be too large for the "
                f"stiffness (dt = {self.dt:.3g} s, {report['fraction']:.3g} of the "
                f"{report['criterion']} {report['critical_time_s']:.3g} s), or "
                "grains started deep inside each other or a wall")
        if status == loop.OVERLAP:
            limit = self.clock[loop.OVERLAP_LIMIT]
            if self.step == 0:
                return OverlapError(
                    f"an overlap exceeds {limit:.3g} of the smaller radius before the "
                    "first step: grains start deep inside each other or behind a "
                    "wall (check the initial positions and the container)")
            return OverlapError(
                f"an overlap exceeded {limit:.3g} of the smaller radius at step "
                f"{self.step} (t = {self.time:.6g} s): grains are too soft for the "
                "load or the time step is too large")
        return None

    def chunk_size(self, end, max_chunk, periods=()):
        """Steps of the next chunk of a run ending at step ``end``: at most max_chunk,
        cut where a period falls, and ending on a multiple of check_interval where it
        can (so the stop condition is tested at the same steps however a run is cut)."""
        n = min(end - self.step, max_chunk)
        for period in periods:
            n = min(n, period - self.step % period)
        check = int(self.counters[loop.CHECK_INTERVAL])
        aligned = (self.step + n) // check * check - self.step
        return aligned if aligned > 0 else n

    # ------------------------------------------------------------------ snapshots
    def snapshot(self):
        """Every mutable array of the run, by name (copies): grains, integrator history,
        contact lists with their histories, walls, clock and counters.  ``restore`` of
        this dict into a Simulation built with the same inputs continues the run bit for
        bit."""
        arrays = {f"grains/{k}": v for k, v in self.state.arrays().items()}
        arrays.update({f"integrator/{k}": v for k, v in self.integrator_state.items()})
        for group, lists in self._lists():
            arrays.update({f"{group}/{k}": v for k, v in lists._asdict().items()
                           if not k.startswith("scratch_") and k not in ("flag", "at")
                           and f"{group}/{k}" not in _TRANSIENT})
        w = self.walls
        arrays.update({"walls/offset": w.offset, "walls/base": w.base,
                       "walls/velocity": w.velocity, "walls/force": w.force,
                       "walls/motion_kind": w.motion_kind, "walls/motion": w.motion,
                       "loop/reference_positions": self.reference_positions,
                       "loop/reference_offset": self.reference_offset,
                       "loop/max_overlap": self.max_overlap, "loop/clock": self.clock,
                       "loop/counters": self.counters,
                       "loop/springs": self.model_ids[PLANAR:PLANAR + 1]})
        return {k: np.array(v, copy=True) for k, v in arrays.items()}

    def _lists(self):
        """(checkpoint group, bundle) of each contact list: pairs, wall contacts and,
        with symmetry planes, the image candidates."""
        lists = [("pairs", self.pairs), ("wall_contacts", self.wall_pairs)]
        return lists + [("images", self.images)] if self.symmetry else lists

    def restore(self, arrays):
        """Put a ``snapshot`` back (same grains, walls and model); ValueError naming the
        arrays that are missing or of the wrong shape."""
        if "loop/springs" not in arrays:
            arrays = _with_planar_springs(arrays, self.model, int(
                self.model_ids[HISTORY + MODES.index("tangential")])) \
                if self.model_ids[PLANAR] else dict(arrays, **{"loop/springs": np.array([0])})
        missing = [k for k in self.snapshot() if k not in arrays]
        if missing:
            raise ValueError(f"snapshot lacks {missing}")
        if np.asarray(arrays["loop/counters"]).size < loop.NCOUNTERS:
            arrays = _with_touching_marks(arrays, self.history_size)
        def put(target, name):
            value = np.asarray(arrays[name])
            if value.shape != target.shape or value.dtype != target.dtype:
                raise ValueError(f"snapshot array {name}: {value.dtype}{value.shape} does "
                                 f"not fit {target.dtype}{target.shape}")
            target[...] = value

        for k, v in self.state.arrays().items():
            put(v, f"grains/{k}")
        for k, v in self.integrator_state.items():
            put(v, f"integrator/{k}")
        def lists(group, bundle):  # scratch arrays are rebuilt empty, like their twins
            return bundle(**{
                k: getattr(self.symmetry, k) if k in ("flag", "at")
                else np.zeros((self.state.n, 6)) if f"{group}/{k}" in _TRANSIENT
                else np.zeros_like(arrays[f"{group}/{k.removeprefix('scratch_')}"])
                if k.startswith("scratch_") else np.array(arrays[f"{group}/{k}"])
                for k in bundle._fields})

        self.pairs = lists("pairs", Pairs)
        self.wall_pairs = lists("wall_contacts", WallPairs)
        if self.symmetry:
            self.images = lists("images", Images)
        motion = np.asarray(arrays["walls/motion"])
        if motion.ndim == 2 and motion.shape[1] == 8:   # written before the piston's mass
            arrays = {**arrays, "walls/motion": np.pad(motion, ((0, 0), (0, 1)))}
        for k in ("offset", "base", "velocity", "force", "motion_kind", "motion"):
            put(getattr(self.walls, k), f"walls/{k}")
        put(self.reference_positions, "loop/reference_positions")
        self.reference_offset = np.array(arrays["loop/reference_offset"])
        for k in ("max_overlap", "clock", "counters"):
            put(getattr(self, k), f"loop/{k}")
        self.state.time = self.time
        self.state.step = self.step

    def rewind(self, arrays):
        """Put the grains, walls and contacts of a ``snapshot`` back while the clock and
        the step counter run on from where they are: the bed as it was, a later time.
        A procedure that undoes what it did since the snapshot uses it, so that the
        time series stay in time order; a wall motion that depends on time (a
        sinusoid, a cyclic load) goes on from the phase it has now, which is the
        snapshot's phase when the time between the two is a whole number of its
        periods.  The energy accumulators come back with the snapshot."""
        time, step, rebuilds = self.time, self.step, self.rebuilds
        self.restore(arrays)
        self.clock[loop.TIME] = time
        self.counters[loop.STEP] = step
        self.counters[loop.REBUILDS] = rebuilds
        self.state.time, self.state.step = time, step

    # ------------------------------------------------------------------ contacts
    def memory_bytes(self):
        """Bytes held by the grain, pair and wall-contact arrays of this simulation (and
        the law loop's workspaces once it has run on the CPU)."""
        arrays = list(self.state.arrays().values()) + list(self.pairs) \
            + list(self.wall_pairs) + list(self.images) \
            + [self.reference_positions, self.max_overlap] \
            + ([a for a in self._law if isinstance(a, np.ndarray)]
               if self._law is not None else [])
        return int(sum(a.nbytes for a in arrays))

    @staticmethod
    def _touching(lists, listed):
        """(owner grain, listed index, force (K, 3) [N]) of the contacts of the lists
        ``lists`` (bundles.Pairs or WallPairs; ``listed`` names its listed indices)
        whose force of the last evaluation is not zero."""
        start, listed, force = lists.start, getattr(lists, listed), lists.force
        n = start.size - 1
        m = int(start[n])
        owner = np.repeat(np.arange(n), np.diff(start))
        touching = np.any(force[:m] != 0.0, axis=1)
        return owner[touching], listed[:m][touching].astype(np.int64), force[:m][touching]

    def contacts(self):
        """The touching grain pairs of the last force evaluation (engine.Contacts).  The
        contact point sits R'_i = R_i - h R_j/(R_i + R_j) from the centre of i along -n,
        h the overlap (engines/soft/contacts.py, Oquendo Eq. 3-4)."""
        i, j, force = self._touching(self.pairs, "partners")
        s = self.state
        separation = self.walls.minimum_image(s.positions[i] - s.positions[j])
        distance = np.linalg.norm(separation, axis=1)
        normal = separation / distance[:, None]
        r_i, r_j = s.radii[i], s.radii[j]
        share = (r_i + r_j - distance) / (r_i + r_j)
        normal_force = np.einsum("ka,ka->k", force, normal)
        return Contacts(i, j, -(r_i - share * r_j)[:, None] * normal,
                        (r_j - share * r_i)[:, None] * normal, normal_force,
                        force - normal_force[:, None] * normal, normal)

    def wall_contacts(self):
        """The touching grain-wall contacts of the last force evaluation
        (engine.WallContacts); the contact point is the foot of the grain's centre on the
        wall."""
        grain, wall, force = self._touching(self.wall_pairs, "ids")
        distance, normal = self.walls.distances(self.state.positions[grain], wall)
        normal_force = np.einsum("ka,ka->k", force, normal)
        return WallContacts(grain, wall, -distance[:, None] * normal, normal_force,
                            force - normal_force[:, None] * normal, normal)

    def image_contacts(self):
        """The touching contacts of grains with the mirror images of grains (symmetry
        planes) at the last force evaluation (engine.ImageContacts); the contact point
        sits as for a pair of grains (contacts)."""
        grain, code, force = self._touching(self.images, "ids")
        s, sym = self.state, self.symmetry
        j, mask = code // MASKS, code % MASKS
        separation = self.walls.minimum_image(s.positions[grain]
                                              - sym.image(s.positions[j], mask))
        distance = np.linalg.norm(separation, axis=1)
        normal = separation / distance[:, None]
        r_i, r_j = s.radii[grain], s.radii[j]
        share = (r_i + r_j - distance) / (r_i + r_j)
        normal_force = np.einsum("ka,ka->k", force, normal)
        return ImageContacts(grain, j, mask, -(r_i - share * r_j)[:, None] * normal,
                             normal_force, force - normal_force[:, None] * normal, normal)

    def energies(self):
        """The energies of engine.ENERGIES [J]: kinetic, rotational and gravitational of
        the free grains, elastic energy of the listed contacts (engines/soft/energy.py;
        half of each image contact's), and the dissipation and wall work the loop accumulates."""
        translational, rotational = kinetic_energy(self.state)
        return {"kinetic": translational, "rotational": rotational,
                "gravitational": gravitational_energy(self.state, self.gravity),
                "elastic": energy.elastic_energy(self.model_ids, self.params, self.state,
                                                 self.walls, self.pairs, self.wall_pairs,
                                                 self.images),
                "dissipated_normal": self.dissipated["normal"],
                "dissipated_tangential": self.dissipated["tangential"],
                "wall_work": self.wall_work}

    # ------------------------------------------------------------------ changes by hand
    @property
    def gravity(self):
        """Gravitational acceleration (3,) [m/s^2] (a copy).  Setting it makes the next
        run evaluate the forces afresh before its first step, so that the step starts
        from accelerations under the new gravity."""
        return self.clock[loop.GX:loop.GZ + 1].copy()

    @gravity.setter
    def gravity(self, value):
        self.clock[loop.GX:loop.GZ + 1] = checked_gravity(value, self.state.dim)
        self.counters[loop.PRIMED] = 0

    def relocate(self, indices, positions, velocities, angular_velocities=None):
        """Move grains ``indices`` to ``positions`` (K, 3) [m] with ``velocities`` (K, 3)
        [m/s] and ``angular_velocities`` (K, 3) [rad/s] (None: zero), between runs or
        from a callback of one (engine.Engine.relocate).

        The rows of their pairs and wall contacts lose their history, force and torque
        (so the contacts they meet at their new place start unloaded), the neighbour
        lists are rebuilt before the next step, and the integrator starts afresh
        (reset_integrator_history: the forces are evaluated again first, and the
        multi-step schemes restart their history for every grain).  The elastic energy
        the relocated grains' contacts held leaves the energy balance, as their
        potential and kinetic energy change."""
        self._move(indices, positions, velocities, angular_velocities, forget=True)

    def _move(self, indices, positions, velocities, angular_velocities=None, forget=True):
        """Move grains (relocate); ``forget`` False keeps the history, forces and torques
        of their contacts, as for grains that moved a little with their contacts (the
        lists, rebuilt before the next step, carry the rows of the pairs still listed)."""
        s = self.state
        idx = s.move(indices, positions, velocities, angular_velocities)
        if idx.size == 0:
            return
        self.counters[loop.FORCE_REBUILD] = 1
        self.reset_integrator_history()
        if not forget:
            return
        chosen = np.zeros(s.n, bool)
        chosen[idx] = True
        for lists, partner in ((self.pairs, "partners"), (self.wall_pairs, None),
                               (self.images, "ids")):
            arrays = lists._asdict()
            start = arrays["start"]
            m = int(start[s.n])
            stale = chosen[np.repeat(np.arange(s.n), np.diff(start))]
            if partner == "partners":         # a pair is listed by one of its two grains
                stale |= chosen[arrays["partners"][:m]]
            elif partner == "ids":            # an image is the image of a grain
                stale |= chosen[arrays["ids"][:m] // MASKS]
            for name in ("history", "force", "torque_j" if partner == "partners" else "torque"):
                arrays[name][:m][stale] = 0.0

    def kick(self, indices, delta_v):
        """Add ``delta_v`` [m/s] to the velocities of grains ``indices`` (engine.Engine.kick):
        their contacts keep their history; the integrator starts afresh."""
        if self.state.kick(indices, delta_v).size:
            self.reset_integrator_history()

    def hold(self, indices):
        """Stop grains ``indices`` and hold them where they are (engine.Engine.hold): they
        become fixed obstacles, out of the energies, until ``release``."""
        self.state.stop(indices)
        self.reset_integrator_history()

    def release(self, indices, positions, velocities, angular_velocities=None):
        """Free held grains ``indices`` at ``positions`` with ``velocities`` (and
        ``angular_velocities``), as relocate puts them (engine.Engine.release)."""
        self.relocate(indices, positions, velocities, angular_velocities)
        self.state.fixed[np.asarray(indices, dtype=np.int64).reshape(-1)] = 0

    def set_motion(self, wall, motion):
        """Prescribe ``motion`` (walls.Motion) to ``wall`` (index or name) from now on
        (engine.Engine.set_motion): the motion starts at its ``start`` [s] or now,
        whichever is later, from where the wall is (a sinusoid's reference place, the
        walls' ``base``, is set there); a fixed wall stops at once."""
        self.walls.prescribe(wall, motion, self.time)

    def set_friction(self, friction=None):
        """Give every material the sliding and static friction coefficients
        (Material.friction_sliding, friction_static) ``friction`` [-] from now on, the
        contact tables rebuilt; None: the materials' own again.  A sample can so be
        prepared with another friction than it is then tested with (frictionless grains
        settle denser, rougher ones looser: SettleSettings.settle_friction).  The
        tangential springs keep their state; a spring longer than the new Coulomb limit
        is cut back to it at its contact's next step, as any law does.  CPU backend only
        (the GPU holds its tables on the device)."""
        if self.backend == "gpu":
            raise ValueError("set_friction runs on the CPU backend only")
        if friction is not None and not friction >= 0:
            raise ValueError(f"friction must be >= 0, got {friction}")
        materials = self.materials if friction is None else [
            dataclasses.replace(m, friction_sliding=float(friction),
                                friction_static=float(friction)) for m in self.materials]
        self.params = self.model.pair_table(materials, self.state.dim)

    def set_servo(self, wall, *, force=None, stress=None, gain=None, time_constant=None,
                  stiffness=None, max_speed=None, direction=None):
        """Make ``wall`` a servo (stress-controlled) wall or change its settings
        (engine.Engine.set_servo; the control law is in walls.py): target ``force`` [N]
        or ``stress`` [Pa] times the wall's area, gain ``gain`` [m/(N s)] or
        1/(``stiffness`` [N/m] ``time_constant`` [s]), largest speed ``max_speed``
        [m/s], ``direction`` into the grains; a setting not given keeps its value on a
        servo wall."""
        self.set_motion(wall, self.walls.servo(
            wall, force=force, stress=stress, gain=gain, time_constant=time_constant,
            stiffness=stiffness, max_speed=max_speed, direction=direction))

    def relax(self, fixed=None, force_tolerance=1e-5, gravity=True, max_iterations=10000,
              anchor=0.0, start=None, keep_contacts=False, allowed=None,
              allowed_walls=None):
        """Move the grains to the minimum of Karrech et al.'s Eq. 29 (Hertz contact
        potentials, gravity, the walls where they are, the images of the symmetry
        planes; relaxation.relax), from rest:
        the free grains are relocated there with zero velocities, without their contact
        history (relocate) unless ``keep_contacts``.  fixed : (N,) bool grains held
        where they are (None: the fixed grains); gravity : False leaves gravity out of
        the functional; anchor : springs holding each grain to where it starts, in
        weights per mean radius (relaxation.relax), which with gravity off make the
        relaxation remove the overlaps moving the grains as little as it can;
        max_iterations of L-BFGS; start : (N, 3) [m] the free grains' positions to
        relax from (None: where they are); keep_contacts : the contacts that are still
        listed after the move keep their history (the tangential springs of Mindlin's
        and Cundall-Strack's laws), as for a configuration moved a little from a
        computed one; allowed : (N, 3) [m] a configuration whose grain-pair overlaps
        are kept, only the excess over them relaxed; allowed_walls : (W, 3) [m] the
        walls' offsets in that configuration, with which the grain-wall contacts keep
        theirs too (relaxation.relax).  Returns the relaxation.Relaxation report."""
        from .relaxation import relax

        held = self.state.fixed != 0 if fixed is None else np.asarray(fixed, bool)
        free = np.flatnonzero(~held)
        rest = np.zeros((free.size, 3))
        if start is not None:
            self._move(free, np.asarray(start, dtype=np.float64)[free], rest,
                       forget=not keep_contacts)
        result = relax(self.state, self.materials, walls=self.walls, fixed=fixed,
                       gravity=self.gravity if gravity else np.zeros(3),
                       force_tolerance=force_tolerance, max_iterations=max_iterations,
                       symmetry=self.symmetry, anchor=anchor, allowed=allowed,
                       allowed_walls=allowed_walls)
        self._move(free, result.positions[free], rest, forget=not keep_contacts)
        return result

    def place_wall(self, wall, offset):
        """Put ``wall`` (index or name) at ``offset`` (3,) [m] from where it was built,
        at once (engine.Engine.place_wall; a sinusoid goes on about the new place).  The
        half-skin rule sees the jump, so the lists are rebuilt before the next step; the
        wall's contacts act from the next force evaluation."""
        self.walls.place(wall, offset)
