"""The soft-particle step on the GPU: the step of engines/soft/loop.run_chunk, one
CUDA thread per grain, built from the CPU's own per-grain functions
(contacts.pair_row and wall_row, integrators.passes.drift_grain and correct_grain,
walls.walls_advance) through device.device_function, for an ensemble of K independent
systems advanced by one set of kernel launches (engines/soft/gpu/layout.py; a single simulation is
the case K = 1).  Systems may differ in grains, walls, materials, time step, gravity,
periodicity and stop condition; they share the contact model and the integrator.

``Simulation(..., backend="gpu")`` runs its chunks here, and so does
``Ensemble(..., backend="gpu")`` (engines/soft/ensemble.py): the arrays go to the device at
the start of a chunk and come back at its end, so everything between chunks (triggers,
outputs, protocols, checkpoints) sees the same host arrays as on the CPU, and a
checkpoint written on one backend resumes on the other.  Within a chunk:
* forces, contact histories, walls and the integrator advance on the device;
* wall totals, energies, the displacement bound and the checks of run_chunk (non-finite
  values, overlap, stop condition, every check_interval steps) are device reductions
  (engines/soft/gpu/reductions.py), per system, and one thread per system ends each step on the
  device (finish_kernel): it counts the step, applies the checks, and masks the system
  out when it stops (its condition, a NaN, an overlap, the end of its steps) or when
  the half-skin rule says its lists must be rebuilt (a pause) while the others go on;
* so the host enqueues steps in batches without reading anything, then reads the
  per-system run table once: it rebuilds the lists of the paused systems on the device
  (engines/soft/gpu/neighbours.py; the list sizes are read back at each build) and resumes them.
  The batch is sized to end about where the next rebuild is expected (DeviceEnsemble._batch),
  so the host is touched about once per rebuild.
System k of an ensemble gives the same numbers, to the bit, as the same system alone.
"""
import math

import numpy as np
from numba import cuda, float64

from ....core.walls import walls_advance
from .. import loop
from ..contacts import gather_grain, pair_row, wall_row
from ..integrators import STAGES
from ..integrators.passes import correct_grain, drift_grain
from .device import device_function
from .layout import ROW, SCRATCH, Layout, bundles, row_grain
from .neighbours import DeviceNeighbours
from .reductions import (ACCELERATION, BAD, COLUMN_OPS, DISPLACED, KINETIC, LOW, MASS,
                         MASS_HEIGHT, OVERLAP, SPEED, SPEED2, SUM, block_rows, fold,
                         move_bound, ops_array, potential_energy)
from .reductions import kernels as reduction_kernels

_KERNELS = {}
COLUMNS = len(COLUMN_OPS)          # of the correction kernel's rows (reductions.py)
# the per-system run table (K, RUN_COLUMNS) int64 that the device keeps within a chunk:
# status (RUNNING, RELIST: paused until the host rebuilds its lists, or a final
# run_chunk code), steps done, steps asked, whether the step under way is checked
# (1, 2: checked without resetting the overlaps), step at the chunk's start, check
# interval, stop condition
STATUS, DONE_STEPS, GOAL, CHECK, FIRST_STEP, INTERVAL, KIND = range(7)
RUN_COLUMNS = 7
RUNNING = -1
# steps enqueued between two reads of the run table: at most, and when nothing
# predicts the next rebuild (engine.DeviceEnsemble._batch)
BATCH_MAX, BATCH_START = 64, 8
# the GPU's pair kernel sums on each grain only the pairs it lists (contacts.pair_row):
# its gather reads back every pair that lists the grain (contacts.gather_grain)
EVERY_PAIR = 1 << 62


def kernels():
    """The CUDA kernels (compiled on first use, once per process)."""
    if _KERNELS:
        return _KERNELS
    drift = device_function(drift_grain)
    pair = device_function(pair_row)
    wall = device_function(wall_row)
    correct = device_function(correct_grain)
    gather = device_function(gather_grain)
    advance = device_function(walls_advance)
    due = device_function(loop.rebuild_due)
    verdict = device_function(loop.verdict)

    @cuda.jit
    def drift_kernel(row_first, row_system, mask, integrator, stage, clock, started, dim,
                     positions, velocities, angular_velocities, orientations, accelerations,
                     angular_accelerations, fixed, history):
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            drift(i, integrator, stage, clock[k, loop.DT], started[k] != 0, dim, positions,
                  velocities, angular_velocities, orientations, accelerations,
                  angular_accelerations, fixed, history)

    @cuda.jit
    def walls_kernel(wb, mask, motion_kind, motion, base, offset, velocity, force, clock):
        """System k's walls moved over its step (thread k)."""
        k = cuda.grid(1)
        if k < mask.size and mask[k] != 0:
            a, b = wb[k], wb[k + 1]
            advance(motion_kind[a:b], motion[a:b], base[a:b], offset[a:b], velocity[a:b],
                    force[a:b], clock[k, loop.TIME], clock[k, loop.DT])

    @cuda.jit
    def force_kernel(row_first, row_system, mask, model, params, positions, velocities,
                     angular_velocities, radii, masses, materials, fixed, periodic_flag,
                     periodic_length, start, partners, history, pair_force, own,
                     pair_torque_j, kind, geometry, offset, velocity, material, wall_start,
                     wall_ids, wall_history, wall_force, wall_torque, max_overlap, lost, ops,
                     clock, scale, divisor, table):
        """Contact forces of grain i over a share scale * dt / divisor of its system's
        step, with its system's pair table params[table[k]]; the energy its contacts
        dissipate, summed over the block (one row) into lost[row] (normal, tangential)
        [J]."""
        buf = cuda.shared.array((ROW, 2), float64)
        t = cuda.threadIdx.x
        k, i, ok = row_grain(row_first, row_system, mask)
        buf[t, 0] = 0.0
        buf[t, 1] = 0.0
        if ok:
            share = scale * clock[k, loop.DT] / divisor
            own_params = params[table[k]]
            dn, dt_ = pair(i, model, own_params, positions, velocities, angular_velocities, radii,
                           masses, materials, fixed, periodic_flag[k], periodic_length[k],
                           start[k:], partners, history, pair_force, own, pair_torque_j,
                           max_overlap, share)
            wn, wt = wall(i, model, own_params, positions, velocities, angular_velocities, radii,
                          masses, materials, kind, geometry, offset, velocity, material,
                          wall_start[k:], wall_ids, wall_history, wall_force, wall_torque,
                          max_overlap, share)
            buf[t, 0] = dn + wn
            buf[t, 1] = dt_ + wt
        block_rows(buf, 2, lost[cuda.blockIdx.x], ops)

    @cuda.jit
    def correct_kernel(row_first, row_system, mask, integrator, stage, clock, scale,
                       started, dim, own, reverse_start, reverse_pairs, pair_force,
                       pair_torque_j, wall_start, wall_force, wall_torque, forces, torques,
                       masses, inertias, positions, reference_positions, velocities,
                       angular_velocities, orientations, accelerations,
                       angular_accelerations, fixed, periodic_flag, periodic_length, history,
                       max_overlap, run, last, rows, ops):
        """Gather and correct grain i (step scale * dt); the bound's measures of the row
        (reductions.DISPLACED ...) go to rows[row], and when the step is checked (the
        ``last`` stage, run[k, CHECK]) the measures of engines/soft/loop._checks too
        (reductions.BAD ...; the grains' largest overlaps are then reset, unless
        run[k, CHECK] is 2)."""
        buf = cuda.shared.array((ROW, COLUMNS), float64)
        t = cuda.threadIdx.x
        k, i, ok = row_grain(row_first, row_system, mask)
        check = run[k, CHECK] if last else 0
        for q in range(COLUMNS):
            buf[t, q] = 0.0
        buf[t, LOW] = math.inf
        if ok:
            f = gather(i, masses[i], clock[k, loop.GX:loop.GZ + 1], own, reverse_start[k:],
                       reverse_pairs, EVERY_PAIR, pair_force, pair_torque_j, wall_start[k:],
                       wall_force, wall_torque)
            buf[t, 0], buf[t, 1], buf[t, 2] = correct(
                i, integrator, stage, scale * clock[k, loop.DT], started[k] != 0, dim, f,
                forces, torques, masses, inertias, positions, reference_positions, velocities,
                angular_velocities, orientations, accelerations, angular_accelerations,
                fixed, periodic_flag[k], periodic_length[k], history)
            if check != 0:
                v2 = 0.0
                w2 = 0.0
                for d in range(3):
                    if not (math.isfinite(positions[i, d]) and math.isfinite(velocities[i, d])
                            and math.isfinite(forces[i, d])):
                        buf[t, BAD] = 1.0
                    v2 += velocities[i, d] ** 2
                    w2 += angular_velocities[i, d] ** 2
                buf[t, OVERLAP] = max_overlap[i]
                if check == 1:
                    max_overlap[i] = 0.0
                if not fixed[i]:
                    buf[t, SPEED2] = v2
                    buf[t, KINETIC] = 0.5 * masses[i] * v2 + 0.5 * inertias[i] * w2
                    gx, gy, gz = clock[k, loop.GX], clock[k, loop.GY], clock[k, loop.GZ]
                    g = math.sqrt(gx ** 2 + gy ** 2 + gz ** 2)
                    if g > 0.0:
                        h = -(positions[i, 0] * gx + positions[i, 1] * gy
                              + positions[i, 2] * gz) / g
                        buf[t, LOW] = h
                        buf[t, MASS_HEIGHT] = masses[i] * h
                        buf[t, MASS] = masses[i]
        block_rows(buf, COLUMNS if check != 0 else 3, rows[cuda.blockIdx.x], ops)

    @cuda.jit
    def decide_kernel(wb, mask, clock, offset, reference_offset, velocity, control):
        """control[k] = 1 when system k's lists must be rebuilt before this step
        (engines/soft/loop.rebuild_due, thread k)."""
        k = cuda.grid(1)
        if k < mask.size:
            a, b = wb[k], wb[k + 1]
            control[k] = 1 if mask[k] != 0 and due(
                clock[k], offset[a:b], reference_offset[a:b], velocity[a:b]) else 0

    @cuda.jit
    def finish_kernel(wb, mask, run, clock, started, folded, offset, reference_offset,
                      velocity):
        """The end of system k's step (thread k): its displacement bound, time, step
        count and checks (engines/soft/loop.verdict) on the device; it stops (mask 0) with its
        status when done, failed or its condition holds, and pauses with RELIST when its
        lists must be rebuilt before the next step (engines/soft/loop.rebuild_due)."""
        k = cuda.grid(1)
        if k >= mask.size or mask[k] == 0:
            return
        clock[k, loop.MOVE] = move_bound(folded[k], clock[k, loop.DT])
        clock[k, loop.TIME] += clock[k, loop.DT]
        started[k] = 1
        done = run[k, DONE_STEPS] + 1
        run[k, DONE_STEPS] = done
        code = loop.DONE
        if run[k, CHECK] != 0:
            code = verdict(folded[k, BAD] == 0.0, folded[k, OVERLAP], folded[k, SPEED2],
                           folded[k, KINETIC], potential_energy(folded[k], clock[k]),
                           run[k, KIND], clock[k])
        if code != loop.DONE or done == run[k, GOAL]:
            run[k, STATUS] = code
            mask[k] = 0
            return
        step = run[k, FIRST_STEP] + done + 1
        run[k, CHECK] = 1 if step % run[k, INTERVAL] == 0 or done + 1 == run[k, GOAL] else 0
        a, b = wb[k], wb[k + 1]
        if due(clock[k], offset[a:b], reference_offset[a:b], velocity[a:b]):
            run[k, STATUS] = loop.RELIST
            mask[k] = 0

    _KERNELS.update(drift=drift_kernel, walls=walls_kernel, force=force_kernel,
                    correct=correct_kernel, decide=decide_kernel, finish=finish_kernel)
    return _KERNELS


class DeviceEnsemble:
    """The device side of K Simulations (backend "gpu"): ``chunk(nsteps)`` is
    engines/soft/loop.run_chunk for each of them on the GPU, with the same return values per
    system.  Same integrators, laws and walls as the CPU; results agree with it to
    floating-point reordering (fused multiply-adds on the device, sums of energies in
    another association), and system k agrees with the same system alone to the bit."""

    def __init__(self, sims):
        self.sims = list(sims)
        self.k = dict(kernels(), **reduction_kernels())
        self.layout = Layout(self.sims)
        self.lists = DeviceNeighbours(self.layout)
        self._masks = {}
        # the run table and the mask of the systems stepping, kept on the device and
        # written by its kernels within a chunk (finish_kernel)
        self.run = cuda.device_array((self.layout.k, RUN_COLUMNS), np.int64)
        self.mask = cuda.device_array(self.layout.k, np.int64)
        # benchmarks set count_bytes: the bytes of the arrays handed to the per-grain
        # kernels, each counted once per launch (an estimate of the memory traffic)
        self.count_bytes = False
        self.launched_bytes = 0
        # reads of the run table between batches, over all chunks (benchmarks, tests);
        # each system's step at its last build (-1: none seen) and the steps between
        # its last two builds (0: not known), for _batch
        self.reads = 0
        self._built = np.full(self.layout.k, -1, np.int64)
        self._cycle = np.zeros(self.layout.k, np.int64)

    def _mask(self, name, values):
        """The device copy of the (K,) int mask ``values``: one array per name, written
        only when the mask changed (no allocation and no copy in most steps)."""
        values = np.asarray(values, np.int64)
        held = self._masks.get(name)
        if held is None:
            held = self._masks[name] = [values.copy(), cuda.to_device(values)]
        elif not np.array_equal(held[0], values):
            held[0][...] = values
            held[1].copy_to_device(values)
        return held[1]

    def _upload(self):
        lay, sims = self.layout, self.sims
        lay.refresh()
        # each group's device arrays in a bundle of its host class (dev["grains"].radii)
        self.dev = {
            group: type(bundle)(**{
                name: cuda.device_array(*lay.shape(group, name)) if (group, name) in SCRATCH
                else cuda.to_device(lay.join(group, name)) for name in bundle._fields})
            for group, bundle in bundles(sims[0]).items()}
        rows, systems = lay.rows, lay.k
        walls = int(np.diff(lay.wb).max())
        self.model = cuda.to_device(sims[0].model_ids)
        self.params = cuda.to_device(lay.params)
        self.started = cuda.to_device(np.array(
            [s.counters[loop.HISTORY_STEPS] > 0 for s in sims], np.int64))
        self.cutoff = cuda.to_device(np.array(
            [2.0 * float(s.state.radii.max()) + s.clock[loop.SKIN] for s in sims]))
        self.control = cuda.device_array(systems, np.int64)
        self.lost = cuda.device_array((rows, 2))
        self.totals = cuda.device_array((rows, 3 * walls + 3))
        self.partial = cuda.device_array((rows, COLUMNS))
        self.folded = cuda.device_array((systems, max(COLUMNS, self.totals.shape[1])))
        self.ops = {"totals": ops_array([SUM] * self.totals.shape[1]),
                    "lost": ops_array([SUM] * 2), "columns": ops_array(COLUMN_OPS)}

    def memory_bytes(self):
        """Bytes of every array this engine keeps on the device (after a chunk or an
        upload): the simulations' arrays, the neighbour-build scratch, the layout tables
        and the reduction rows.  The CUDA context and numba's own allocations are not
        counted."""
        arrays = [a for bundle in self.dev.values() for a in bundle]
        arrays += [self.model, self.params, self.started, self.cutoff, self.control,
                   self.run, self.mask, self.lost, self.totals, self.partial, self.folded,
                   *self.ops.values(), *self.layout.dev.values()]
        return sum(a.nbytes for a in arrays) + self.lists.memory_bytes()

    def _download(self):
        for group, arrays in self.dev.items():
            for name, dev in arrays._asdict().items():
                if (group, name) not in SCRATCH:
                    self.layout.split(group, name, dev.copy_to_host())

    def _rebuild(self, due):
        """Device-side neighbour build (engines/soft/gpu/neighbours.py) of the systems with due[k].
        When a list outgrows its slots, that system's arrays are grown on the host as
        the CPU loop does (the old lists kept) and the build runs again.  Returns the
        systems whose positions are not finite (nothing rebuilt)."""
        while True:
            need_p, need_w, bad = self.lists.build(
                due, self._mask("due", due), self.dev["grains"], self.dev["pairs"],
                self.dev["walls"], self.dev["periodic"], self.dev["loop"].clock, self.cutoff)
            if bad.any():
                return bad
            grow_p = need_p > np.diff(self.layout.pb)
            grow_w = need_w > np.diff(self.layout.cb)
            if not (grow_p.any() or grow_w.any()):
                break
            self._download()
            for k in np.flatnonzero(grow_p):
                self.sims[k]._allocate_pairs(int(1.3 * need_p[k]) + 64)
            for k in np.flatnonzero(grow_w):
                self.sims[k]._allocate_walls(int(1.3 * need_w[k]) + 16)
            started = self.started        # the host counters are behind within a chunk
            self._upload()
            self.started = started
        return bad

    def _rows(self, name, mask, *args):
        """Kernel ``name`` with one block per row of the layout, one thread per grain."""
        lay = self.layout
        self.k[name][lay.rows, lay.threads](lay.dev["row_first"], lay.dev["row_system"],
                                            mask, *args)
        if self.count_bytes:
            self.launched_bytes += sum(getattr(a, "nbytes", 0) for a in args)

    def _systems(self, name, *args):
        """Kernel ``name`` with one thread per system."""
        systems = self.layout.k
        threads = min(systems, 128)
        self.k[name][(systems + threads - 1) // threads, threads](*args)

    def _evaluate(self, mask, scale, divisor):
        """Forces of the masked systems, for a share scale * dt / divisor of the step."""
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        clock, lay = self.dev["loop"].clock, self.layout
        self._rows("force", mask, self.model, self.params, g.positions, g.velocities,
                   g.angular_velocities, g.radii, g.masses, g.materials, g.fixed, per.flag,
                   per.length, p.start, p.partners, p.history, p.force, p.own, p.torque_j,
                   w.kind, w.geometry, w.offset, w.velocity, w.material, w.wall_start,
                   w.wall_ids, w.wall_history, w.contact_force, w.contact_torque,
                   g.max_overlap, self.lost, self.ops["lost"], clock, scale, divisor,
                   lay.dev["table"])
        threads = min(lay.rows, 128)
        self.k["totals_partial"][(lay.rows + threads - 1) // threads, threads](
            lay.dev["row_first"], lay.dev["row_system"], lay.dev["wb"], mask, w.wall_start,
            w.wall_ids, w.contact_force, w.velocity, self.lost, self.totals)
        # the view of as many columns as the rows have (totals_apply counts the walls by it)
        totals = self.folded[:, :self.totals.shape[1]]
        fold(self.k, lay, self.totals, self.ops["totals"], totals)
        self._systems("totals_apply", totals, lay.dev["wb"], mask, w.force, clock, scale,
                      divisor)

    def _correct(self, mask, stage, scale, last):
        """Gather and correct the masked systems (scale * dt), and fold the rows of the
        correction kernel into ``folded`` (the bound; on a checked ``last`` stage, the
        checks too)."""
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        clock, lay = self.dev["loop"].clock, self.layout
        integrator = int(self.sims[0].counters[loop.INTEGRATOR])
        self._rows("correct", mask, integrator, stage, clock, scale, self.started,
                   int(self.sims[0].counters[loop.DIM]), p.own, p.reverse_start,
                   p.reverse_pairs, p.force, p.torque_j, w.wall_start, w.contact_force,
                   w.contact_torque, g.forces, g.torques, g.masses, g.inertias, g.positions,
                   g.reference_positions, g.velocities, g.angular_velocities, g.orientations,
                   g.accelerations, g.angular_accelerations, g.fixed, per.flag, per.length,
                   self.dev["loop"].integrator_history, g.max_overlap, self.run, last,
                   self.partial, self.ops["columns"])
        fold(self.k, lay, self.partial, self.ops["columns"], self.folded[:, :COLUMNS])

    def _step(self, integrator, stages):
        """Enqueue one step of every system the device mask holds: nothing is read
        back; finish_kernel stops or pauses the systems."""
        mask, clock, w = self.mask, self.dev["loop"].clock, self.dev["walls"]
        for stage in range(stages):
            g = self.dev["grains"]
            self._rows("drift", mask, integrator, stage, clock, self.started,
                       int(self.sims[0].counters[loop.DIM]), g.positions,
                       g.velocities, g.angular_velocities, g.orientations, g.accelerations,
                       g.angular_accelerations, g.fixed, self.dev["loop"].integrator_history)
            if stage == 0:
                self._systems("walls", self.layout.dev["wb"], mask, w.motion_kind, w.motion,
                              w.base, w.offset, w.velocity, w.force, clock)
            self._evaluate(mask, 1.0, float(stages))
            last = stage == stages - 1
            self._correct(mask, stage, 1.0, last)
            if last:
                self._systems("finish", self.layout.dev["wb"], mask, self.run, clock,
                              self.started, self.folded, w.offset, w.reference_offset,
                              w.velocity)
            else:
                self._systems("bound_apply", self.folded, mask, clock, 1.0)

    def chunk(self, nsteps):
        """Up to nsteps[k] steps of each system k on the device: (status (K,), steps done
        (K,)), as run_chunk for each (RELIST never comes back: lists are rebuilt and grown
        here)."""
        self._upload()
        try:
            return self._steps(np.asarray(nsteps, np.int64))
        finally:
            self._download()
            for sim in self.sims:
                sim.state.time = sim.time
                sim.state.step = sim.step

    def _steps(self, nsteps):
        """The chunk: lists forced or due rebuilt and unprimed systems primed first,
        then batches of steps enqueued without a read; after each batch one read of the
        run table says which systems stopped or paused for a rebuild (the host builds
        their lists and resumes them) and how many steps the next batch gets."""
        sims, systems = self.sims, self.layout.k
        counters = np.stack([s.counters for s in sims])     # host copy, written back
        integrator = int(counters[0, loop.INTEGRATOR])
        stages = int(STAGES[integrator])
        table = np.zeros((systems, RUN_COLUMNS), np.int64)
        table[:, STATUS] = np.where(nsteps > 0, RUNNING, loop.DONE)
        table[:, GOAL] = nsteps
        table[:, FIRST_STEP] = counters[:, loop.STEP]
        table[:, INTERVAL] = counters[:, loop.CHECK_INTERVAL]
        table[:, KIND] = counters[:, loop.COND_KIND]
        rebuilt = np.zeros(systems, np.int64)
        try:
            running = table[:, STATUS] == RUNNING
            forced = running & (counters[:, loop.FORCE_REBUILD] != 0)
            table[forced | self._due(running & ~forced), STATUS] = loop.RELIST
            self._resume(table, rebuilt)
            prime = (table[:, STATUS] == RUNNING) & (counters[:, loop.PRIMED] == 0)
            if prime.any():
                self._prime(prime, table, counters)
            first = table[:, FIRST_STEP] + 1
            table[:, CHECK] = (first % table[:, INTERVAL] == 0) | (table[:, GOAL] == 1)
            self.run.copy_to_device(table)
            self.mask.copy_to_device((table[:, STATUS] == RUNNING).astype(np.int64))
            batch = self._batch(table, first=True)
            while (table[:, STATUS] == RUNNING).any():
                for _ in range(batch):
                    self._step(integrator, stages)
                table = self.run.copy_to_host()
                self.reads += 1
                if (table[:, STATUS] == loop.RELIST).any():
                    self._resume(table, rebuilt)
                    self.run.copy_to_device(table)
                    self.mask.copy_to_device((table[:, STATUS] == RUNNING).astype(np.int64))
                batch = self._batch(table)
        finally:
            done = table[:, DONE_STEPS]
            counters[:, loop.STEP] += done
            counters[:, loop.HISTORY_STEPS] += done
            counters[:, loop.REBUILDS] += rebuilt
            counters[rebuilt > 0, loop.FORCE_REBUILD] = 0
            for k, sim in enumerate(sims):
                sim.counters[...] = counters[k]
        return table[:, STATUS].copy(), done.copy()

    def _due(self, which):
        """The systems of the boolean mask ``which`` whose lists must be rebuilt before
        their next step (engines/soft/loop.rebuild_due, on the device; one read)."""
        if not which.any():
            return which
        w = self.dev["walls"]
        self._systems("decide", self.layout.dev["wb"], self._mask("decide", which),
                      self.dev["loop"].clock, w.offset, w.reference_offset, w.velocity,
                      self.control)
        return which & (self.control.copy_to_host() != 0)

    def _resume(self, table, rebuilt):
        """Rebuild the lists of the systems paused with RELIST in the run table (host
        copy) and set them RUNNING again, or NAN where their positions are not
        finite."""
        due = table[:, STATUS] == loop.RELIST
        if not due.any():
            return
        bad = self._rebuild(due.astype(np.int64)) != 0
        table[due & bad, STATUS] = loop.NAN
        ok = due & ~bad
        table[ok, STATUS] = RUNNING
        rebuilt[ok] += 1
        now = table[ok, FIRST_STEP] + table[ok, DONE_STEPS]
        last = self._built[ok]
        self._cycle[ok] = np.where(last >= 0, now - last, 0)
        self._built[ok] = now

    def _prime(self, prime, table, counters):
        """The forces at the start of the run of the systems of the boolean mask
        ``prime``; those whose grains start too deep in each other or in a wall stop
        with OVERLAP before their first step."""
        mask = self._mask("prime", prime)
        table[prime, CHECK] = 2                 # measure the overlaps, do not reset them
        self.run.copy_to_device(table)
        self._evaluate(mask, 0.0, 1.0)
        self._correct(mask, 0, 0.0, True)
        self._systems("bound_apply", self.folded, mask, self.dev["loop"].clock, 0.0)
        counters[prime, loop.PRIMED] = 1
        worst = self.folded.copy_to_host()[:, OVERLAP]
        limits = np.array([s.clock[loop.OVERLAP_LIMIT] for s in self.sims])
        table[prime & (worst > limits), STATUS] = loop.OVERLAP

    def _batch(self, table, first=False):
        """Steps in the next batch: the steps left before the next rebuild of the running
        systems (the lowest tenth of them), from 1 to BATCH_MAX and no more than any of
        them has left.  From the last step's folded rows, the grain furthest from its
        place at the build (d, 0 just after a build) is assumed to go on at the largest
        speed v and acceleration a of its system: the bound d + v T + a T^2 / 2
        (reductions.move_bound, T = (m + 1) dt) passes half the skin at the m-th step
        from now, whose finish pauses the system; and no further than its last cycle
        between two builds, if it is not past it (grains that speed up or were briefly
        at rest).  The ``first`` batch of a chunk has no rows to go by: BATCH_START steps,
        within the same bounds.  Only the speed depends on it: a batch too long leaves a
        paused system idle to its end, one too short costs a read."""
        running = table[:, STATUS] == RUNNING
        if not running.any():
            return 0
        built, cycle = self._built[running], self._cycle[running]
        steps = (table[:, FIRST_STEP] + table[:, DONE_STEPS])[running] - built
        if first:
            ahead = np.full(built.size, float(BATCH_START))
        else:
            folded = self.folded.copy_to_host()[running]
            clock = self.dev["loop"].clock.copy_to_host()[running]
            d = np.where((built >= 0) & (steps == 0), 0.0, np.sqrt(folded[:, DISPLACED]))
            v, a = np.sqrt(folded[:, SPEED]), np.sqrt(folded[:, ACCELERATION])
            room = np.maximum(0.5 * clock[:, loop.SKIN] - d, 0.0)
            # the root T of a T^2 / 2 + v T = room, in the form that holds for a = 0
            root = v + np.sqrt(v * v + 2.0 * a * room)
            with np.errstate(divide="ignore"):
                ahead = np.where(root > 0.0,
                                 np.floor(2.0 * room / root / clock[:, loop.DT]), BATCH_MAX)
        within = (built >= 0) & (cycle > steps)
        ahead[within] = np.minimum(ahead[within], (cycle - steps)[within])
        left = (table[:, GOAL] - table[:, DONE_STEPS])[running]
        ahead = min(float(np.quantile(ahead, 0.1, method="lower")), float(left.min()))
        return int(np.clip(ahead, 1, BATCH_MAX))
