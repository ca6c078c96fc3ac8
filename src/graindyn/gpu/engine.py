"""The soft-particle step on the GPU (issue 6): the step of core/loop.run_chunk, one
CUDA thread per grain, built from the CPU's own per-grain functions
(contacts.pair_row and wall_row, integrators.passes.drift_grain and correct_grain,
walls.walls_advance) through device.device_function, for an ensemble of K independent
systems advanced by one set of kernel launches (gpu/layout.py; a single simulation is
the case K = 1).  Systems may differ in grains, walls, materials, time step, gravity,
periodicity and stop condition; they share the contact model and the integrator.

``Simulation(..., backend="gpu")`` runs its chunks here, and so does
``Ensemble(..., backend="gpu")`` (core/ensemble.py): the arrays go to the device at
the start of a chunk and come back at its end, so everything between chunks (triggers,
outputs, protocols, checkpoints) sees the same host arrays as on the CPU, and a
checkpoint written on one backend resumes on the other.  Within a chunk:
* forces, contact histories, walls and the integrator advance on the device;
* the neighbour lists are built on the device (gpu/neighbours.py) when the half-skin
  rule, evaluated on the device for each system, asks for it; the host reads those
  flags back each step, and the list sizes at each rebuild;
* wall totals, energies, the displacement bound and the checks of run_chunk (non-finite
  values, overlap, stop condition, every check_interval steps) are device reductions
  (gpu/reductions.py), per system; a system that stops (its condition, a NaN, an
  overlap, or the end of its steps) is masked out while the others go on.
System k of an ensemble gives the same numbers, to the bit, as the same system alone.
"""
import math

import numpy as np
from numba import cuda, float64

from ..core import loop
from ..core.contacts import gather_grain, pair_row, wall_row
from ..core.integrators import STAGES
from ..core.integrators.passes import correct_grain, drift_grain
from ..core.walls import walls_advance
from .device import device_function
from .layout import ROW, SCRATCH, Layout, bundles, row_grain
from .neighbours import DeviceNeighbours
from .reductions import (BAD, CHECK_OPS, KINETIC, MAX, OVERLAP, POTENTIAL, SPEED2, SUM,
                         block_rows, fold, ops_array)
from .reductions import kernels as reduction_kernels

_KERNELS = {}
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

    @cuda.jit
    def drift_kernel(row_first, row_system, mask, integrator, stage, clock, started,
                     positions, velocities, angular_velocities, orientations, accelerations,
                     angular_accelerations, fixed, history):
        k, i, ok = row_grain(row_first, row_system, mask)
        if ok:
            drift(i, integrator, stage, clock[k, loop.DT], started[k] != 0, positions,
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
                       bound, ops):
        """Gather and correct grain i (step scale * dt); the largest squared
        displacement since the last build, speed and acceleration of the row go to
        bound[row]."""
        buf = cuda.shared.array((ROW, 3), float64)
        t = cuda.threadIdx.x
        k, i, ok = row_grain(row_first, row_system, mask)
        buf[t, 0] = 0.0
        buf[t, 1] = 0.0
        buf[t, 2] = 0.0
        if ok:
            f = gather(i, masses[i], clock[k, loop.GX:loop.GZ + 1], own, reverse_start[k:],
                       reverse_pairs, EVERY_PAIR, pair_force, pair_torque_j, wall_start[k:],
                       wall_force, wall_torque)
            buf[t, 0], buf[t, 1], buf[t, 2] = correct(
                i, integrator, stage, scale * clock[k, loop.DT], started[k] != 0, dim, f,
                forces, torques, masses, inertias, positions, reference_positions, velocities,
                angular_velocities, orientations, accelerations, angular_accelerations,
                fixed, periodic_flag[k], periodic_length[k], history)
        block_rows(buf, 3, bound[cuda.blockIdx.x], ops)

    @cuda.jit
    def decide_kernel(wb, mask, clock, offset, reference_offset, velocity, control):
        """control[k] = 1 when system k's lists must be rebuilt before this step
        (core/loop.rebuild_due, thread k)."""
        k = cuda.grid(1)
        if k < mask.size:
            a, b = wb[k], wb[k + 1]
            control[k] = 1 if mask[k] != 0 and due(
                clock[k], offset[a:b], reference_offset[a:b], velocity[a:b]) else 0

    @cuda.jit
    def tick_kernel(mask, clock, started):
        k = cuda.grid(1)
        if k < mask.size and mask[k] != 0:
            clock[k, loop.TIME] += clock[k, loop.DT]
            started[k] = 1

    _KERNELS.update(drift=drift_kernel, walls=walls_kernel, force=force_kernel,
                    correct=correct_kernel, decide=decide_kernel, tick=tick_kernel)
    return _KERNELS


class DeviceEnsemble:
    """The device side of K Simulations (backend "gpu"): ``chunk(nsteps)`` is
    core/loop.run_chunk for each of them on the GPU, with the same return values per
    system.  Same integrators, laws and walls as the CPU; results agree with it to
    floating-point reordering (fused multiply-adds on the device, sums of energies in
    another association), and system k agrees with the same system alone to the bit."""

    def __init__(self, sims):
        self.sims = list(sims)
        self.k = dict(kernels(), **reduction_kernels())
        self.layout = Layout(self.sims)
        self.lists = DeviceNeighbours(self.layout)
        self._masks = {}
        # benchmarks set count_bytes: the bytes of the arrays handed to the per-grain
        # kernels, each counted once per launch (an estimate of the memory traffic)
        self.count_bytes = False
        self.launched_bytes = 0

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
        self.dev = {}
        for group, arrays in bundles(sims[0]).items():
            self.dev[group] = [
                cuda.device_array(*lay.shape(group, q)) if (group, q) in SCRATCH
                else cuda.to_device(lay.join(group, q)) for q in range(len(arrays))]
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
        self.partial = cuda.device_array((rows, 6))
        self.checked = cuda.device_array((systems, 6))
        self.folded = cuda.device_array((systems, max(6, self.totals.shape[1])))
        self.ops = {"totals": ops_array([SUM] * self.totals.shape[1]),
                    "lost": ops_array([SUM] * 2), "bound": ops_array([MAX] * 3),
                    "checks": ops_array(CHECK_OPS)}

    def memory_bytes(self):
        """Bytes of every array this engine keeps on the device (after a chunk or an
        upload): the simulations' arrays, the neighbour-build scratch, the layout tables
        and the reduction rows.  The CUDA context and numba's own allocations are not
        counted."""
        arrays = [a for bundle in self.dev.values() for a in bundle]
        arrays += [self.model, self.params, self.started, self.cutoff, self.control,
                   self.lost, self.totals, self.partial, self.checked, self.folded,
                   *self.ops.values(), *self.layout.dev.values()]
        return sum(a.nbytes for a in arrays) + self.lists.memory_bytes()

    def _download(self):
        for group, arrays in self.dev.items():
            for q, dev in enumerate(arrays):
                if (group, q) not in SCRATCH:
                    self.layout.split(group, q, dev.copy_to_host())

    def _rebuild(self, due):
        """Device-side neighbour build (gpu/neighbours.py) of the systems with due[k].
        When a list outgrows its slots, that system's arrays are grown on the host as
        the CPU loop does (the old lists kept) and the build runs again.  Returns the
        systems whose positions are not finite (nothing rebuilt)."""
        while True:
            need_p, need_w, bad = self.lists.build(
                due, self._mask("due", due), self.dev["grains"], self.dev["pairs"],
                self.dev["walls"], self.dev["periodic"], self.dev["loop"][0], self.cutoff)
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
        clock, lay = self.dev["loop"][0], self.layout
        self._rows("force", mask, self.model, self.params, g[0], g[1], g[2], g[8], g[9],
                   g[11], g[12], per[0], per[2], p[0], p[1], p[2], p[8], p[9], p[10], w[0],
                   w[1], w[5], w[6], w[7], w[10], w[11], w[12], w[16], w[17], g[14],
                   self.lost, self.ops["lost"], clock, scale, divisor, lay.dev["table"])
        self.k["totals_partial"][(lay.rows + 127) // 128, 128](
            lay.dev["row_first"], lay.dev["row_system"], lay.dev["wb"], mask, w[10], w[11],
            w[16], w[6], self.lost, self.totals)
        fold(self.k, lay, self.totals, self.ops["totals"], self.folded)
        self._systems("totals_apply", self.folded, lay.dev["wb"], mask, w[8], clock, scale,
                      divisor)

    def _correct(self, mask, stage, scale):
        g, p, w, per = (self.dev[k] for k in ("grains", "pairs", "walls", "periodic"))
        clock, lay = self.dev["loop"][0], self.layout
        integrator = int(self.sims[0].counters[loop.INTEGRATOR])
        self._rows("correct", mask, integrator, stage, clock, scale, self.started,
                   int(self.sims[0].counters[loop.DIM]), p[9], p[6], p[7], p[8], p[10],
                   w[10], w[16], w[17], g[4], g[5], g[9], g[10], g[0], g[13], g[1], g[2], g[3],
                   g[6], g[7], g[12], per[0], per[2], self.dev["loop"][1], self.partial,
                   self.ops["bound"])
        fold(self.k, lay, self.partial[:, :3], self.ops["bound"], self.folded[:, :3])
        self._systems("bound_apply", self.folded[:, :3], mask, clock, scale)

    def _check(self, mask, reset):
        """The reductions of core/loop._checks for the masked systems: (K, 6) indexed by
        reductions.BAD ... POTENTIAL; their max_overlap is set back to zero when
        ``reset``."""
        g, lay = self.dev["grains"], self.layout
        clock = self.dev["loop"][0]
        blocks = (lay.rows + 127) // 128
        self.k["checks_partial"][blocks, 128](
            lay.dev["row_first"], lay.dev["row_system"], mask, g[0], g[1], g[2], g[4], g[9],
            g[10], g[12], g[14], clock, reset, self.partial)
        fold(self.k, lay, self.partial[:, :POTENTIAL], self.ops["checks"],
             self.checked[:, :POTENTIAL])
        self.k["potential_partial"][blocks, 128](
            lay.dev["row_first"], lay.dev["row_system"], mask, g[0], g[9], g[12], clock,
            self.checked, self.partial)
        fold(self.k, lay, self.partial[:, POTENTIAL:], self.ops["checks"][POTENTIAL:],
             self.checked[:, POTENTIAL:])
        return self.checked.copy_to_host()

    def _statuses(self, mask):
        """core/loop._checks on the device results: a run_chunk status code for each
        masked system (DONE for the others)."""
        out = self._check(self._mask("check", mask), True)
        status = np.full(self.layout.k, loop.DONE)
        for k in np.flatnonzero(mask):
            clock, counters = self.sims[k].clock, self.sims[k].counters
            kind, value = counters[loop.COND_KIND], clock[loop.COND_VALUE]
            if out[k, BAD] != 0.0:
                status[k] = loop.NAN
            elif out[k, OVERLAP] > clock[loop.OVERLAP_LIMIT]:
                status[k] = loop.OVERLAP
            elif kind == loop.MAX_SPEED_BELOW and math.sqrt(out[k, SPEED2]) < value:
                status[k] = loop.CONDITION
            elif kind == loop.ENERGY_RATIO_BELOW and \
                    out[k, KINETIC] <= value * out[k, POTENTIAL]:
                status[k] = loop.CONDITION
        return status

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
        sims, systems = self.sims, self.layout.k
        status = np.full(systems, loop.DONE)
        done = np.zeros(systems, np.int64)
        active = (nsteps > 0).astype(np.int64)
        counters = np.stack([s.counters for s in sims])     # host copy, written back
        integrator = int(counters[0, loop.INTEGRATOR])
        stages = int(STAGES[integrator])

        def stop(which, code, steps):
            status[which] = code
            done[which] = steps
            active[which] = 0

        s = 0
        try:
            while active.any():
                clock, w = self.dev["loop"][0], self.dev["walls"]
                forced = active * (counters[:, loop.FORCE_REBUILD] != 0)
                due = forced.copy()
                if (active & ~forced.astype(bool)).any():
                    self._systems("decide", self.layout.dev["wb"],
                                  self._mask("decide", active - forced), clock, w[5], w[9],
                                  w[6], self.control)
                    due |= (active - forced) * self.control.copy_to_host()
                if due.any():
                    bad = self._rebuild(due)
                    if bad.any():
                        stop(bad != 0, loop.NAN, s)
                        continue
                    counters[due != 0, loop.FORCE_REBUILD] = 0
                    counters[due != 0, loop.REBUILDS] += 1
                    clock, w = self.dev["loop"][0], self.dev["walls"]    # may be new
                mask = self._mask("active", active)
                prime = active * (counters[:, loop.PRIMED] == 0)
                if prime.any():
                    primed = self._mask("prime", prime)
                    self._evaluate(primed, 0.0, 1.0)
                    self._correct(primed, 0, 0.0)
                    counters[prime != 0, loop.PRIMED] = 1
                    # grains that start too deep in each other or in a wall: stop first
                    worst = self._check(primed, False)[:, OVERLAP]
                    limits = np.array([x.clock[loop.OVERLAP_LIMIT] for x in sims])
                    deep = (prime != 0) & (worst > limits)
                    if deep.any():
                        stop(deep, loop.OVERLAP, s)
                        if not active.any():
                            break
                        mask = self._mask("active", active)
                for stage in range(stages):
                    g = self.dev["grains"]
                    self._rows("drift", mask, integrator, stage, clock, self.started, g[0],
                               g[1], g[2], g[3], g[6], g[7], g[12], self.dev["loop"][1])
                    if stage == 0:
                        self._systems("walls", self.layout.dev["wb"], mask, w[2], w[3], w[4],
                                      w[5], w[6], w[8], clock)
                    self._evaluate(mask, 1.0, float(stages))
                    self._correct(mask, stage, 1.0)
                self._systems("tick", mask, clock, self.started)
                counters[active != 0, loop.STEP] += 1
                counters[active != 0, loop.HISTORY_STEPS] += 1
                s += 1
                check = active * ((counters[:, loop.STEP] % counters[:, loop.CHECK_INTERVAL]
                                   == 0) | (nsteps == s))
                if check.any():
                    codes = self._statuses(check)
                    halted = (check != 0) & (codes != loop.DONE)
                    for code in np.unique(codes[halted]):
                        stop(halted & (codes == code), code, s)
                stop((active != 0) & (nsteps == s), loop.DONE, s)
        finally:
            for k, sim in enumerate(sims):
                sim.counters[...] = counters[k]
        return status, done
